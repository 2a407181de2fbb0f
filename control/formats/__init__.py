"""The controller-side forms of a validated file: ROS 2 messages and goals, the drive
table, rosbag2 bags and their replay files."""
