"""Robot backends: the simulator (sim) and ROS 2 (ros2). Only the CLI wires them in."""
