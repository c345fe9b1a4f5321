"""Live 3D view in Foxglove: pure geometry (``geometry``), the viewer's parameters
(``specs``) and the Foxglove channels (``view``); the ROS node is ``nodes/viewer.py``."""
