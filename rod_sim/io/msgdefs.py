"""ROS 2 message definitions (``ros2msg`` schemas) of the topics rod_sim publishes and logs.

The texts are embedded so that writing and reading logs works without ROS installed. Each is
the full concatenated definition exactly as rosbag2 Jazzy writes it into an MCAP schema
(``rosbag2_cpp::LocalMessageDefinitionSource::get_full_text``): the type's own ``.msg`` file,
comments included, then for each dependency, depth first, each once, in the sorted order of
the names found in the referring file::

    <previous text>\\n
    ================================================================================\\n
    MSG: pkg/Type\\n
    <text of pkg/msg/Type.msg>

:data:`SCHEMAS` maps type names (``sensor_msgs/msg/JointState``) to those texts and
:data:`TYPE_HASHES` to the type's RIHS01 hash (channel metadata ``topic_type_hash``).
:func:`full_definition` rebuilds a text from ``.msg`` files; regenerate the constants with
``python -m rod_sim.io.msgdefs SHARE_DIR > constants.txt`` (SHARE_DIR holds ``<pkg>/msg/*.msg``).

Why the texts are copied rather than read from the installed interface packages (issue 21):
the ROS 2 wheels that ship the ``.msg`` files (``ros-jazzy-common-interfaces``, under
``<sys.prefix>/share/<pkg>/msg``) are the optional ``ros`` extra, and ``rod-sim simulate``,
``compare`` and ``repair`` write and read logs without it (``pip install rod_sim``); the
libraries cannot stand in either: rosbags' ``generate_msgdef`` drops the comments that rosbag2
keeps in the schema text, and mcap_ros2 has no definitions. test/test_msgdefs.py checks that
every copied text equals the one rebuilt from the installed ``.msg`` files (and fails, rather
than skips, when the ``ros`` extra is installed but a file is missing), and the hashes and
fields against rosbags' Jazzy type store.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Callable

SEPARATOR = "=" * 80 + "\n"

# Same pattern as rosbag2's MSG_FIELD_TYPE_REGEX: the first word of every line is a field type.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_PRIMITIVES = frozenset({"bool", "byte", "char", "float32", "float64", "int8", "uint8", "int16",
                         "uint16", "int32", "uint32", "int64", "uint64", "string"})
_MAX_DEPTH = 50

MsgSource = Callable[[str, str], str]
"""``source(package, type) -> text`` of ``<package>/msg/<type>.msg``."""


def _dependencies(text: str, package: str) -> list[str]:
    """Sorted non-primitive field types of a ``.msg`` text, as ``pkg/Type``."""
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        name = match.group(1)
        if name in _PRIMITIVES:
            continue
        deps.add(name if "/" in name else f"{package}/{name}")
    return sorted(deps)


def _split(type_name: str) -> tuple[str, str]:
    parts = type_name.split("/")
    if len(parts) == 2:
        return parts[0], parts[1]
    if len(parts) == 3 and parts[1] == "msg":
        return parts[0], parts[2]
    raise ValueError(f"not a message type name: {type_name!r}")


def full_definition(type_name: str, source: MsgSource) -> str:
    """The concatenated definition of ``type_name`` (``pkg/msg/Type``), as rosbag2 Jazzy builds it."""
    seen: set[str] = set()

    def append(name: str, depth: int) -> str:
        if depth <= 0:
            raise ValueError(f"recursion too deep resolving {type_name}")
        package, msg = _split(name)
        text = source(package, msg)
        out = text
        for dep in _dependencies(text, package):
            if dep not in seen:
                seen.add(dep)
                out += "\n" + SEPARATOR + f"MSG: {dep}\n" + append(dep, depth - 1)
        return out

    return append(type_name, _MAX_DEPTH)


def share_source(share_dir: str | Path) -> MsgSource:
    """A :data:`MsgSource` reading ``<share_dir>/<pkg>/msg/<Type>.msg`` (UTF-8, bytes kept)."""
    root = Path(share_dir)

    def source(package: str, msg: str) -> str:
        return (root / package / "msg" / f"{msg}.msg").read_bytes().decode("utf-8")

    return source


def _render_constants(share_dir: str | Path) -> str:
    """Python source of the generated block below (each ``.msg`` text once, and the type
    hashes), regenerated from ``share_dir``."""
    source = share_source(share_dir)
    used: dict[str, str] = {}

    def recording(package: str, msg: str) -> str:
        used[f"{package}/{msg}"] = text = source(package, msg)
        return text

    for type_name in TYPE_NAMES:
        full_definition(type_name, recording)
    lines = ["MSG_FILES: dict[str, str] = {"]
    for name in sorted(used):
        lines.append(f"    {name!r}: (")
        for line in used[name].splitlines(keepends=True):
            lines.append(f"        {line!r}")
        lines.append("    ),")
    lines.append("}")
    lines.append("")
    lines.append("TYPE_HASHES: dict[str, str] = {")
    for type_name in TYPE_NAMES:
        package, msg = _split(type_name)
        info = json.loads((Path(share_dir) / package / "msg" / f"{msg}.json").read_text())
        digest = next(h["hash_string"] for h in info["type_hashes"] if h["type_name"] == type_name)
        lines.append(f"    {type_name!r}: {digest!r},")
    lines.append("}")
    return "\n".join(lines) + "\n"


TYPE_NAMES = (
    "sensor_msgs/msg/JointState",
    "geometry_msgs/msg/PoseArray",
    "std_msgs/msg/Float64MultiArray",
    "visualization_msgs/msg/MarkerArray",
    "diagnostic_msgs/msg/DiagnosticArray",
    "rosgraph_msgs/msg/Clock",
    "std_msgs/msg/String",
    "geometry_msgs/msg/WrenchStamped",
    "nav_msgs/msg/Odometry",
)
"""The message types rod_sim writes, keys of :data:`SCHEMAS` and :data:`TYPE_HASHES`."""

# ----- generated by _render_constants from the ROS 2 Jazzy share directory: the text of every
# ``.msg`` file the types above use (key ``pkg/Type``), and the type hashes -----
# GENERATED-SCHEMAS-BEGIN
MSG_FILES: dict[str, str] = {
    'builtin_interfaces/Duration': (
        '# Duration defines a period between two time points.\n'
        '# Messages of this datatype are of ROS Time following this design:\n'
        '# https://design.ros2.org/articles/clock_and_time.html\n'
        '\n'
        '# The seconds component, valid over all int32 values.\n'
        'int32 sec\n'
        '\n'
        '# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component. \n'
        '# e.g.\n'
        '# The duration -1.7 seconds is represented as {sec: -2, nanosec: 3e8}\n'
        '# The duration 1.7 seconds is represented as {sec: 1, nanosec: 7e8}\n'
        'uint32 nanosec\n'
    ),
    'builtin_interfaces/Time': (
        '# This message communicates ROS Time defined here:\n'
        '# https://design.ros2.org/articles/clock_and_time.html\n'
        '\n'
        '# The seconds component, valid over all int32 values.\n'
        'int32 sec\n'
        '\n'
        '# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component. \n'
        '# e.g.\n'
        '# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}\n'
        '# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}\n'
        'uint32 nanosec\n'
    ),
    'diagnostic_msgs/DiagnosticArray': (
        '# This message is used to send diagnostic information about the state of the robot.\n'
        'std_msgs/Header header # for timestamp\n'
        'DiagnosticStatus[] status # an array of components being reported on\n'
    ),
    'diagnostic_msgs/DiagnosticStatus': (
        '# This message holds the status of an individual component of the robot.\n'
        '\n'
        '# Possible levels of operations.\n'
        'byte OK=0\n'
        'byte WARN=1\n'
        'byte ERROR=2\n'
        'byte STALE=3\n'
        '\n'
        '# Level of operation enumerated above.\n'
        'byte level\n'
        '# A description of the test/component reporting.\n'
        'string name\n'
        '# A description of the status.\n'
        'string message\n'
        '# A hardware unique string.\n'
        'string hardware_id\n'
        '# An array of values associated with the status.\n'
        'KeyValue[] values\n'
        '\n'
    ),
    'diagnostic_msgs/KeyValue': (
        '# What to label this value when viewing.\n'
        'string key\n'
        '# A value to track over time.\n'
        'string value\n'
    ),
    'geometry_msgs/Point': (
        '# This contains the position of a point in free space\n'
        'float64 x\n'
        'float64 y\n'
        'float64 z\n'
    ),
    'geometry_msgs/Pose': (
        '# A representation of pose in free space, composed of position and orientation.\n'
        '\n'
        'Point position\n'
        'Quaternion orientation\n'
    ),
    'geometry_msgs/PoseArray': (
        '# An array of poses with a header for global reference.\n'
        '\n'
        'std_msgs/Header header\n'
        '\n'
        'Pose[] poses\n'
    ),
    'geometry_msgs/PoseWithCovariance': (
        '# This represents a pose in free space with uncertainty.\n'
        '\n'
        'Pose pose\n'
        '\n'
        '# Row-major representation of the 6x6 covariance matrix\n'
        '# The orientation parameters use a fixed-axis representation.\n'
        '# In order, the parameters are:\n'
        '# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)\n'
        'float64[36] covariance\n'
    ),
    'geometry_msgs/Quaternion': (
        '# This represents an orientation in free space in quaternion form.\n'
        '\n'
        'float64 x 0\n'
        'float64 y 0\n'
        'float64 z 0\n'
        'float64 w 1\n'
    ),
    'geometry_msgs/Twist': (
        '# This expresses velocity in free space broken into its linear and angular parts.\n'
        '\n'
        'Vector3  linear\n'
        'Vector3  angular\n'
    ),
    'geometry_msgs/TwistWithCovariance': (
        '# This expresses velocity in free space with uncertainty.\n'
        '\n'
        'Twist twist\n'
        '\n'
        '# Row-major representation of the 6x6 covariance matrix\n'
        '# The orientation parameters use a fixed-axis representation.\n'
        '# In order, the parameters are:\n'
        '# (x, y, z, rotation about X axis, rotation about Y axis, rotation about Z axis)\n'
        'float64[36] covariance\n'
    ),
    'geometry_msgs/Vector3': (
        '# This represents a vector in free space.\n'
        '\n'
        '# This is semantically different than a point.\n'
        '# A vector is always anchored at the origin.\n'
        '# When a transform is applied to a vector, only the rotational component is applied.\n'
        '\n'
        'float64 x\n'
        'float64 y\n'
        'float64 z\n'
    ),
    'geometry_msgs/Wrench': (
        '# This represents force in free space, separated into its linear and angular parts.\n'
        '\n'
        'Vector3  force\n'
        'Vector3  torque\n'
    ),
    'geometry_msgs/WrenchStamped': (
        '# A wrench with reference coordinate frame and timestamp\n'
        '\n'
        'std_msgs/Header header\n'
        'Wrench wrench\n'
    ),
    'nav_msgs/Odometry': (
        '# This represents an estimate of a position and velocity in free space.\n'
        '# The pose in this message should be specified in the coordinate frame given by header.frame_id\n'
        '# The twist in this message should be specified in the coordinate frame given by the child_frame_id\n'
        '\n'
        '# Includes the frame id of the pose parent.\n'
        'std_msgs/Header header\n'
        '\n'
        '# Frame id the pose points to. The twist is in this coordinate frame.\n'
        'string child_frame_id\n'
        '\n'
        '# Estimated pose that is typically relative to a fixed world frame.\n'
        'geometry_msgs/PoseWithCovariance pose\n'
        '\n'
        '# Estimated linear and angular velocity relative to child_frame_id.\n'
        'geometry_msgs/TwistWithCovariance twist\n'
    ),
    'rosgraph_msgs/Clock': (
        '# This message communicates the current time.\n'
        '#\n'
        '# For more information, see https://design.ros2.org/articles/clock_and_time.html.\n'
        'builtin_interfaces/Time clock\n'
    ),
    'sensor_msgs/CompressedImage': (
        '# This message contains a compressed image.\n'
        '\n'
        'std_msgs/Header header # Header timestamp should be acquisition time of image\n'
        '                             # Header frame_id should be optical frame of camera\n'
        '                             # origin of frame should be optical center of cameara\n'
        '                             # +x should point to the right in the image\n'
        '                             # +y should point down in the image\n'
        '                             # +z should point into to plane of the image\n'
        '\n'
        'string format                # Specifies the format of the data\n'
        '                             # Acceptable values differ by the image transport used:\n'
        '                             # - compressed_image_transport:\n'
        '                             #     ORIG_PIXFMT; CODEC compressed [COMPRESSED_PIXFMT]\n'
        '                             #   where:\n'
        '                             #   - ORIG_PIXFMT is pixel format of the raw image, i.e.\n'
        '                             #     the content of sensor_msgs/Image/encoding with\n'
        '                             #     values from include/sensor_msgs/image_encodings.h\n'
        '                             #   - CODEC is one of [jpeg, png, tiff]\n'
        '                             #   - COMPRESSED_PIXFMT is only appended for color images\n'
        '                             #     and is the pixel format used by the compression\n'
        '                             #     algorithm. Valid values for jpeg encoding are:\n'
        '                             #     [bgr8, rgb8]. Valid values for png encoding are:\n'
        '                             #     [bgr8, rgb8, bgr16, rgb16].\n'
        '                             #   If the field is empty or does not correspond to the\n'
        '                             #   above pattern, the image is treated as bgr8 or mono8\n'
        '                             #   jpeg image (depending on the number of channels).\n'
        '                             # - compressed_depth_image_transport:\n'
        '                             #     ORIG_PIXFMT; compressedDepth CODEC\n'
        '                             #   where:\n'
        '                             #   - ORIG_PIXFMT is pixel format of the raw image, i.e.\n'
        '                             #     the content of sensor_msgs/Image/encoding with\n'
        '                             #     values from include/sensor_msgs/image_encodings.h\n'
        '                             #     It is usually one of [16UC1, 32FC1].\n'
        '                             #   - CODEC is one of [png, rvl]\n'
        '                             #   If the field is empty or does not correspond to the\n'
        '                             #   above pattern, the image is treated as png image.\n'
        '                             # - Other image transports can store whatever values they\n'
        '                             #   need for successful decoding of the image. Refer to\n'
        '                             #   documentation of the other transports for details.\n'
        '\n'
        'uint8[] data                 # Compressed image buffer\n'
    ),
    'sensor_msgs/JointState': (
        '# This is a message that holds data to describe the state of a set of torque controlled joints.\n'
        '#\n'
        '# The state of each joint (revolute or prismatic) is defined by:\n'
        '#  * the position of the joint (rad or m),\n'
        '#  * the velocity of the joint (rad/s or m/s) and\n'
        '#  * the effort that is applied in the joint (Nm or N).\n'
        '#\n'
        '# Each joint is uniquely identified by its name\n'
        '# The header specifies the time at which the joint states were recorded. All the joint states\n'
        '# in one message have to be recorded at the same time.\n'
        '#\n'
        '# This message consists of a multiple arrays, one for each part of the joint state.\n'
        '# The goal is to make each of the fields optional. When e.g. your joints have no\n'
        '# effort associated with them, you can leave the effort array empty.\n'
        '#\n'
        '# All arrays in this message should have the same size, or be empty.\n'
        '# This is the only way to uniquely associate the joint name with the correct\n'
        '# states.\n'
        '\n'
        'std_msgs/Header header\n'
        '\n'
        'string[] name\n'
        'float64[] position\n'
        'float64[] velocity\n'
        'float64[] effort\n'
    ),
    'std_msgs/ColorRGBA': (
        'float32 r\n'
        'float32 g\n'
        'float32 b\n'
        'float32 a\n'
    ),
    'std_msgs/Float64MultiArray': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        '# Please look at the MultiArrayLayout message definition for\n'
        '# documentation on all multiarrays.\n'
        '\n'
        'MultiArrayLayout  layout        # specification of data layout\n'
        'float64[]         data          # array of data\n'
    ),
    'std_msgs/Header': (
        '# Standard metadata for higher-level stamped data types.\n'
        '# This is generally used to communicate timestamped data\n'
        '# in a particular coordinate frame.\n'
        '\n'
        '# Two-integer timestamp that is expressed as seconds and nanoseconds.\n'
        'builtin_interfaces/Time stamp\n'
        '\n'
        '# Transform frame with which this data is associated.\n'
        'string frame_id\n'
    ),
    'std_msgs/MultiArrayDimension': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        'string label   # label of given dimension\n'
        'uint32 size    # size of given dimension (in type units)\n'
        'uint32 stride  # stride of given dimension\n'
    ),
    'std_msgs/MultiArrayLayout': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        '# The multiarray declares a generic multi-dimensional array of a\n'
        '# particular data type.  Dimensions are ordered from outer most\n'
        '# to inner most.\n'
        '#\n'
        '# Accessors should ALWAYS be written in terms of dimension stride\n'
        '# and specified outer-most dimension first.\n'
        '#\n'
        '# multiarray(i,j,k) = data[data_offset + dim_stride[1]*i + dim_stride[2]*j + k]\n'
        '#\n'
        '# A standard, 3-channel 640x480 image with interleaved color channels\n'
        '# would be specified as:\n'
        '#\n'
        '# dim[0].label  = "height"\n'
        '# dim[0].size   = 480\n'
        '# dim[0].stride = 3*640*480 = 921600  (note dim[0] stride is just size of image)\n'
        '# dim[1].label  = "width"\n'
        '# dim[1].size   = 640\n'
        '# dim[1].stride = 3*640 = 1920\n'
        '# dim[2].label  = "channel"\n'
        '# dim[2].size   = 3\n'
        '# dim[2].stride = 3\n'
        '#\n'
        '# multiarray(i,j,k) refers to the ith row, jth column, and kth channel.\n'
        '\n'
        'MultiArrayDimension[] dim # Array of dimension properties\n'
        'uint32 data_offset        # padding bytes at front of data\n'
    ),
    'std_msgs/String': (
        '# This was originally provided as an example message.\n'
        '# It is deprecated as of Foxy\n'
        '# It is recommended to create your own semantically meaningful message.\n'
        '# However if you would like to continue using this please use the equivalent in example_msgs.\n'
        '\n'
        'string data\n'
    ),
    'visualization_msgs/Marker': (
        '# See:\n'
        '#  - http://www.ros.org/wiki/rviz/DisplayTypes/Marker\n'
        '#  - http://www.ros.org/wiki/rviz/Tutorials/Markers%3A%20Basic%20Shapes\n'
        '#\n'
        '# for more information on using this message with rviz.\n'
        '\n'
        'int32 ARROW=0\n'
        'int32 CUBE=1\n'
        'int32 SPHERE=2\n'
        'int32 CYLINDER=3\n'
        'int32 LINE_STRIP=4\n'
        'int32 LINE_LIST=5\n'
        'int32 CUBE_LIST=6\n'
        'int32 SPHERE_LIST=7\n'
        'int32 POINTS=8\n'
        'int32 TEXT_VIEW_FACING=9\n'
        'int32 MESH_RESOURCE=10\n'
        'int32 TRIANGLE_LIST=11\n'
        'int32 ARROW_STRIP=12\n'
        '\n'
        'int32 ADD=0\n'
        'int32 MODIFY=0\n'
        'int32 DELETE=2\n'
        'int32 DELETEALL=3\n'
        '\n'
        '# Header for timestamp and frame id.\n'
        'std_msgs/Header header\n'
        '# Namespace in which to place the object.\n'
        '# Used in conjunction with id to create a unique name for the object.\n'
        'string ns\n'
        '# Object ID used in conjunction with the namespace for manipulating and deleting the object later.\n'
        'int32 id\n'
        '# Type of object.\n'
        'int32 type\n'
        '# Action to take; one of:\n'
        '#  - 0 add/modify an object\n'
        '#  - 1 (deprecated)\n'
        '#  - 2 deletes an object (with the given ns and id)\n'
        '#  - 3 deletes all objects (or those with the given ns if any)\n'
        'int32 action\n'
        '# Pose of the object with respect the frame_id specified in the header.\n'
        'geometry_msgs/Pose pose\n'
        '# Scale of the object; 1,1,1 means default (usually 1 meter square).\n'
        'geometry_msgs/Vector3 scale\n'
        '# Color of the object; in the range: [0.0-1.0]\n'
        'std_msgs/ColorRGBA color\n'
        '# How long the object should last before being automatically deleted.\n'
        '# 0 indicates forever.\n'
        'builtin_interfaces/Duration lifetime\n'
        '# If this marker should be frame-locked, i.e. retransformed into its frame every timestep.\n'
        'bool frame_locked\n'
        '\n'
        '# Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, ARROW_STRIP, etc.)\n'
        'geometry_msgs/Point[] points\n'
        '# Only used if the type specified has some use for them (eg. POINTS, LINE_STRIP, etc.)\n'
        '# The number of colors provided must either be 0 or equal to the number of points provided.\n'
        '# NOTE: alpha is not yet used\n'
        'std_msgs/ColorRGBA[] colors\n'
        '\n'
        '# Texture resource is a special URI that can either reference a texture file in\n'
        '# a format acceptable to (resource retriever)[https://docs.ros.org/en/rolling/p/resource_retriever/]\n'
        '# or an embedded texture via a string matching the format:\n'
        '#   "embedded://texture_name"\n'
        'string texture_resource\n'
        '# An image to be loaded into the rendering engine as the texture for this marker.\n'
        '# This will be used iff texture_resource is set to embedded.\n'
        'sensor_msgs/CompressedImage texture\n'
        '# Location of each vertex within the texture; in the range: [0.0-1.0]\n'
        'UVCoordinate[] uv_coordinates\n'
        '\n'
        '# Only used for text markers\n'
        'string text\n'
        '\n'
        '# Only used for MESH_RESOURCE markers.\n'
        '# Similar to texture_resource, mesh_resource uses resource retriever to load a mesh.\n'
        '# Optionally, a mesh file can be sent in-message via the mesh_file field. If doing so,\n'
        '# use the following format for mesh_resource:\n'
        '#   "embedded://mesh_name"\n'
        'string mesh_resource\n'
        'MeshFile mesh_file\n'
        'bool mesh_use_embedded_materials\n'
    ),
    'visualization_msgs/MarkerArray': (
        'Marker[] markers\n'
    ),
    'visualization_msgs/MeshFile': (
        '# Used to send raw mesh files.\n'
        '\n'
        '# The filename is used for both debug purposes and to provide a file extension\n'
        '# for whatever parser is used.\n'
        'string filename\n'
        '\n'
        '# This stores the raw text of the mesh file.\n'
        'uint8[] data\n'
    ),
    'visualization_msgs/UVCoordinate': (
        '# Location of the pixel as a ratio of the width of a 2D texture.\n'
        '# Values should be in range: [0.0-1.0].\n'
        'float32 u\n'
        'float32 v\n'
    ),
}

TYPE_HASHES: dict[str, str] = {
    'sensor_msgs/msg/JointState': 'RIHS01_a13ee3a330e346c9d87b5aa18d24e11690752bd33a0350f11c5882bc9179260e',
    'geometry_msgs/msg/PoseArray': 'RIHS01_af0cc36d190e104d546d168d6b39df04fa4b4ccecf59cb4c9ed328d3d5004aa0',
    'std_msgs/msg/Float64MultiArray': 'RIHS01_1025ddc6b9552d191f89ef1a8d2f60f3d373e28b283d8891ddcc974e8c55397f',
    'visualization_msgs/msg/MarkerArray': 'RIHS01_86cb8800b6fb05b5eff1abd7a56f62a5641d3ae9a1c29e78e67e704f1d067dcf',
    'diagnostic_msgs/msg/DiagnosticArray': 'RIHS01_5a8a36efb05fb25070fa0fb3810290c0e6cd4862b54a8fb975a1ee8dc55a333e',
    'rosgraph_msgs/msg/Clock': 'RIHS01_692f7a66e93a3c83e71765d033b60349ba68023a8c689a79e48078bcb5c58564',
    'std_msgs/msg/String': 'RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18',
    'geometry_msgs/msg/WrenchStamped': 'RIHS01_8dc3deaf06b2ab281f9f9a742a8961c328ca7cec16e3fd6586d3a5c83fa78f77',
    'nav_msgs/msg/Odometry': 'RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0',
}
# GENERATED-SCHEMAS-END

SCHEMAS: dict[str, str] = {
    name: full_definition(name, lambda package, msg: MSG_FILES[f"{package}/{msg}"])
    for name in TYPE_NAMES}
"""Type name -> the full concatenated definition rosbag2 writes as the MCAP schema."""

class MessageFieldError(ValueError):
    """A message dict has a field its ROS type does not define; ``str(err)`` names its path
    (raised by the encoders of :mod:`rod_sim.io.cdr`)."""


if __name__ == "__main__":
    sys.stdout.write(_render_constants(sys.argv[1] if len(sys.argv) > 1 else "."))
