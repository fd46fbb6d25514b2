"""Robot backends: the simulator (sim), ROS 2 (ros2), recordings (recorded); only the session wires them."""
