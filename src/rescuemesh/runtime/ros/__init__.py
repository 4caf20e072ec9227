"""ROS bodies: the same brain, navigation and protocol on a ROS 1 or ROS 2 robot (odometry, poses and scans
in, Twist out), and the paper's ROS interface (rescuemesh_msgs Command topics, the SendCommand action)."""
