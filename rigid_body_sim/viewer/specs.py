"""The viewer node's parameters (``attitude_viewer``): one spec list, free of ROS."""
from ..param_spec import ParamSpec

LOOPBACK = ('127.0.0.1', 'localhost', '::1')

VIEWER = (
    ParamSpec('host', '127.0.0.1', 'address the Foxglove WebSocket server binds to; anything '
              'but loopback (e.g. 0.0.0.0) serves the simulation to the network, unauthenticated',
              kind='string', read_only=True),
    ParamSpec('port', 8765, 'TCP port of the Foxglove WebSocket server (0 = any free port, '
              'logged)', kind='int', low=0, high=65535, read_only=True),
    ParamSpec('mcap_output', '', 'also write every Foxglove channel to this MCAP file '
              '(Foxglove-only playback; the ROS bag is the recorder\'s); empty = off',
              kind='string', read_only=True, path=True),
    ParamSpec('simulator_node', 'attitude_simulator', 'name of the simulator node whose '
              'inertia parameter gives the body (in this node\'s namespace)', kind='string',
              read_only=True),
    ParamSpec('controller_node', 'attitude_controller', 'name of the controller node whose '
              'target_attitude gives the pointing error (if it runs)', kind='string',
              read_only=True),
    ParamSpec('scene_rate', 10.0, 'rate of 3D scene updates (box, arrows, Poinsot\'s '
              'construction); the transform and plot channels follow every sample',
              kind='float', unit='Hz', low=0.1, high=1000.0),
    ParamSpec('body_size', 1.0, 'longest edge of the displayed box; the Poinsot view is '
              'scaled so that the first energy ellipsoid\'s longest semi-axis has this length',
              kind='float', unit='m', low=1e-6, high=1e6, low_open=True),
    ParamSpec('trace_length', 600, 'points kept in the polhode and herpolhode traces',
              kind='int', low=2, high=100000),
    ParamSpec('qos', 'reliable', 'QoS of the state subscriptions (as the simulator\'s)',
              kind='string', choices=('reliable', 'sensor_data'), read_only=True),
)
