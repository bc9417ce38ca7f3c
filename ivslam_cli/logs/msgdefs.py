"""The project's own landmark message, defined once and embedded in every log we write.

ROS 2 name ``ivslam_msgs/msg/LandmarkObservations``; ROS 1 name
``ivslam_msgs/LandmarkObservations``. One message holds every observation of one step:
parallel arrays of landmark id, range [m] and bearing [rad, robot frame, CCW from x].
"""

LANDMARK_MSG_ROS2 = "ivslam_msgs/msg/LandmarkObservations"
LANDMARK_MSG_ROS1 = "ivslam_msgs/LandmarkObservations"

LANDMARK_MSG_DEF = """\
std_msgs/Header header
int32[] id
float64[] range
float64[] bearing
"""
