"""ROS: recordings (bags) into kinecal's files, hand-eye results out as static transforms.

No paper: this package connects kinecal to the ROS world.

* `kinecal.io.ros.bag`: ROS 1 bags and ROS 2 bags (sqlite3, mcap) opened through the
  ``rosbags`` library (the ``kinecal[ros]`` extra; imported only here, `require_rosbags`),
  streamed topic by topic.
* `kinecal.io.ros.messages`: the messages kinecal reads (JointState, PointStamped,
  PoseStamped, TransformStamped, TFMessage, Image, CompressedImage, CameraInfo) as numbers.
* `kinecal.io.ros.dwell`: where the robot dwells (joint speeds below a tolerance for a
  stated time), found chunk by chunk with numpy.
* `kinecal.io.ros.importer`: `import_bag`, the dwell rows of a bag (joints and averaged
  measurements, partial dwells dropped with their reason); `kinecal.io.ros.images`: the
  images and camera of each dwell, written as a folder ``kinecal handeye-images`` reads.
* `kinecal.io.ros.static_tf`: a hand-eye result as a ``tf2_ros static_transform_publisher``
  (command-line arguments and a ROS 2 launch file).
"""

from kinecal.errors import InputError

__all__ = ["EXTRA_HINT", "require_rosbags"]

#: how to install what reading a bag needs
EXTRA_HINT = "pip install kinecal[ros]"


def require_rosbags():
    """``rosbags.highlevel`` (AnyReader); `InputError` naming the extra when it is not installed."""
    try:
        import rosbags.highlevel
    except ImportError:
        raise InputError("reading ROS bags needs the rosbags library, which is not "
                         f"installed: {EXTRA_HINT}") from None
    return rosbags.highlevel
