"""Short scripts that drive the live nodes from Python (rclpy), runnable from the venv."""
