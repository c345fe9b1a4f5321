"""rosbag2-compatible MCAP bags (ROS 2 Jazzy): write, read, inspect, recover.

The writer needs no ROS graph: give it serialized CDR bytes
(``rclpy.serialization.serialize_message``) and it writes what ``ros2 bag record -s mcap``
would, so offline runs and the live recorder produce the same files.

The names below are imported on first use (module ``__getattr__``): ``from .bag.errors
import BagError`` (every offline run, a refused one included) then does not import the
writer and mcap (~0.05 CPU-s).
"""
from ..lazy_exports import lazy_exports

_HOME = {'BagError': 'errors', 'DEFAULT_QOS_YAML': 'schema', 'message_definition': 'schema',
         'type_hash': 'schema', 'RUN_CONFIGURATION': 'writer', 'BagWriter': 'writer'}

__all__ = ['BagError', 'BagWriter', 'DEFAULT_QOS_YAML', 'RUN_CONFIGURATION',
           'message_definition', 'type_hash']


__getattr__, __dir__ = lazy_exports(__name__, globals(), _HOME)
