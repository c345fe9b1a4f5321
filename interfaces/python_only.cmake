# Included by both interface packages after their dependencies are found and before
# rosidl_generate_interfaces. rclpy loads only the C code and the C typesupports
# (fastrtps_c for rmw_fastrtps_cpp, introspection_c); the C++ headers and typesupports
# would double the build time for nothing a Python process uses, so their generators are
# dropped unless INTERFACES_WITH_CPP is ON (then the build has every generator of a full
# install). Types, hashes and the wire format come from the same definitions either way.
option(INTERFACES_WITH_CPP "also generate the C++ headers and typesupports" OFF)
if(NOT INTERFACES_WITH_CPP)
  list(FILTER AMENT_EXTENSIONS_rosidl_generate_idl_interfaces EXCLUDE REGEX
    "^rosidl_(generator_cpp|typesupport_cpp|typesupport_fastrtps_cpp|typesupport_introspection_cpp):")
endif()
