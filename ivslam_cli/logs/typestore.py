"""rosbags typestores with the project's landmark message registered.

Every reader and writer gets its typestore here, so the landmark message is defined
once (``msgdefs.LANDMARK_MSG_DEF``) and is always known, even for bags that embed
no definitions (ROS 2 Humble sqlite3 bags). A file that embeds the definitions of the types
it is read for (MCAP schemas) gets a store of just those (:func:`typestore_from_schemas`):
building the whole Humble store costs ~0.1 s of a short run.
"""

from __future__ import annotations

from collections.abc import Iterable
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


def typestore_from_schemas(ros: int, schemas: Iterable[tuple[str, str, bytes]], wanted: Iterable[str]):
    """A store of the definitions a file embeds, ``(type name, encoding, text)`` each (MCAP
    ``ros2msg`` / ``ros1msg`` schemas, dependencies included), plus ``LandmarkObservations``; the
    full :func:`typestore` when a ``wanted`` type, or a type it uses, is not defined there or a
    text does not parse."""
    from rosbags.typesys import TypesysError

    encoding = "ros1msg" if ros == 1 else "ros2msg"
    store = get_typestore(Stores.EMPTY)
    try:
        store.register(get_types_from_msg(LANDMARK_MSG_DEF, LANDMARK_MSG_ROS2))
        for name, enc, text in schemas:
            if enc == encoding:
                store.register(get_types_from_msg(text.decode(), name))
        for w in wanted:  # every type a wanted one uses is defined too (raises otherwise)
            store.generate_msgdef(w)
    except (TypesysError, UnicodeDecodeError, KeyError):
        return typestore(ros)
    return store
