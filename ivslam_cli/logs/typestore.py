"""rosbags typestores with the project's landmark message registered.

Every reader and writer gets its typestore here, so the landmark message is defined
once (``msgdefs.LANDMARK_MSG_DEF``) and is always known, even for bags that embed
no definitions (ROS 2 Humble sqlite3 bags).
"""

from __future__ import annotations

from functools import lru_cache

from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from ivslam_cli.logs.msgdefs import LANDMARK_MSG_DEF, LANDMARK_MSG_ROS2

TF_MESSAGE = "tf2_msgs/msg/TFMessage"


@lru_cache(maxsize=None)
def typestore(ros: int = 2):
    """The ROS 1 (Noetic) or ROS 2 (Humble) typestore plus ``LandmarkObservations``."""
    store = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(LANDMARK_MSG_DEF, LANDMARK_MSG_ROS2))
    if TF_MESSAGE not in store.types:  # rosbags' Noetic store lacks tf2_msgs
        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF_MESSAGE))
    return store
