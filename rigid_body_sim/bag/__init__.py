"""rosbag2-compatible MCAP bags (ROS 2 Jazzy): write, read, inspect, recover.

The writer needs no ROS graph: give it serialized CDR bytes
(``rclpy.serialization.serialize_message``) and it writes what ``ros2 bag record -s mcap``
would, so offline runs and the live recorder produce the same files.
"""
from rigid_body_sim.bag.errors import BagError
from rigid_body_sim.bag.schema import DEFAULT_QOS_YAML, message_definition, type_hash
from rigid_body_sim.bag.writer import RUN_CONFIGURATION, BagWriter

__all__ = ['BagError', 'BagWriter', 'DEFAULT_QOS_YAML', 'RUN_CONFIGURATION',
           'message_definition', 'type_hash']
