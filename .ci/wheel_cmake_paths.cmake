# Injected into the interface builds with CMAKE_PROJECT_INCLUDE by .ci/build_interfaces.sh.
#
# The ROS 2 PyPI wheels were built in a manylinux container, and the CMake export files
# of their Python typesupport targets (<pkg>::<pkg>__rosidl_generator_py, e.g. of
# geometry_msgs) still name that container's include directories,
# /opt/python/cp3XX-cp3XX/include/python3.X and .../numpy/_core/include. CMake refuses
# to generate a build that links to an imported target with a missing include directory.
# Those two directories only stand for Python's and NumPy's headers, which
# rosidl_generator_py adds anyway from this venv's interpreter, so the stale entries are
# dropped from the imported targets: at the end of configuration, once every
# find_package() has run, and in memory only, so the wheels' files stay as installed.
function(_rbs_drop_manylinux_include_dirs)
  get_property(_targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs)
      continue()
    endif()
    set(_kept "")
    foreach(_dir IN LISTS _dirs)
      if(_dir MATCHES "^/opt/python/cp[0-9]+-cp[0-9]+/" AND NOT EXISTS "${_dir}")
        continue()
      endif()
      list(APPEND _kept "${_dir}")
    endforeach()
    if(NOT "${_kept}" STREQUAL "${_dirs}")
      set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_kept}")
    endif()
  endforeach()
endfunction()
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL _rbs_drop_manylinux_include_dirs)
