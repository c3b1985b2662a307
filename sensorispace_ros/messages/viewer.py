"""What viewers draw (Foxglove, RViz): markers for ``core.scene``'s shapes, a
coloured PointCloud2 (FLOAT32 x, y, z and a packed ``rgb``, RViz's convention,
read by Foxglove too) and Float64MultiArray series for plots."""
from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

from sensorispace_ros.messages.clouds import table_to_cloud

#
# Foxglove and RViz read these standard messages: markers for core.scene's
# shapes, a PointCloud2 with FLOAT32 x, y, z and a packed ``rgb`` (RViz's
# convention, read by Foxglove too), and Float64MultiArray series for plots.

def packed_rgb(rgb: np.ndarray) -> np.ndarray:
    """RGB in [0, 1], (n, 3), as float32 whose bits are 0x00RRGGBB (a ``rgb`` field)."""
    rgb = np.asarray(rgb, dtype=float).reshape(-1, 3)
    if not np.all((rgb >= 0.0) & (rgb <= 1.0)):
        raise ValueError("rgb: every component must lie in [0, 1]")
    levels = np.rint(rgb * 255.0).astype(np.uint32)
    return ((levels[:, 0] << 16) | (levels[:, 1] << 8) | levels[:, 2]).view(np.float32)


def coloured_cloud(xyz: np.ndarray, rgb: np.ndarray, ids: np.ndarray,
                   columns: Mapping[str, str], header: Header) -> PointCloud2:
    """Points ``xyz`` (n, 3) coloured ``rgb`` (n, 3 in [0, 1]) and named by ``ids``,
    as a cloud of ``columns`` (x, y, z, rgb as float32, then the id column)."""
    xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
    ids = np.asarray(ids).reshape(-1)
    if not len(xyz) == len(ids) == len(np.asarray(rgb).reshape(-1, 3)):
        raise ValueError(f"xyz, rgb and ids differ in length: {len(xyz)}, "
                         f"{len(np.asarray(rgb).reshape(-1, 3))}, {len(ids)}")
    names = list(columns)
    if names[:4] != ["x", "y", "z", "rgb"] or len(names) != 5:
        raise ValueError(f"columns must be x, y, z, rgb and an id column, got {names}")
    table = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "rgb": packed_rgb(rgb),
             names[4]: ids}
    return table_to_cloud(table, columns, header)


def shape_to_marker(shape, header: Header):
    """A ``core.scene.Shape`` as a ``visualization_msgs/Marker``: id 0 of its
    namespace, in the header's frame."""
    from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
    from std_msgs.msg import ColorRGBA
    from visualization_msgs.msg import Marker

    types = {"line_strip": Marker.LINE_STRIP, "line_list": Marker.LINE_LIST,
             "spheres": Marker.SPHERE_LIST, "points": Marker.POINTS}
    r, g, b, a = (float(c) for c in shape.colour)
    size = float(shape.size)
    return Marker(
        header=header, ns=shape.namespace, id=0, type=types[shape.kind],
        action=Marker.ADD, pose=Pose(orientation=Quaternion(w=1.0)),
        scale=Vector3(x=size, y=size, z=size), color=ColorRGBA(r=r, g=g, b=b, a=a),
        points=[Point(x=x, y=y, z=z) for x, y, z in np.asarray(shape.points, dtype=float).tolist()])


def shapes_to_marker_array(shapes, header: Header):
    """``core.scene.Shape`` s as a ``visualization_msgs/MarkerArray`` (``shape_to_marker``)."""
    from visualization_msgs.msg import MarkerArray

    return MarkerArray(markers=[shape_to_marker(shape, header) for shape in shapes])


def values_to_multiarray(values, labels: Sequence[str]):
    """Named values as a ``std_msgs/Float64MultiArray`` (one dimension, its label
    the names joined by commas): ``data[i]`` is ``labels[i]``, as Foxglove's Plot
    panel addresses it (``/topic.data[i]``)."""
    from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout

    values = np.asarray(values, dtype=float).reshape(-1)
    if len(values) != len(labels):
        raise ValueError(f"{len(values)} values for {len(labels)} labels")
    dim = MultiArrayDimension(label=",".join(labels), size=len(values), stride=len(values))
    return Float64MultiArray(layout=MultiArrayLayout(dim=[dim], data_offset=0),
                             data=values.tolist())


def pixels_to_image(pixels, width: int, height: int, header: Header):
    """A camera's receptors (rows top first, each pixel's channels together:
    ``height * width`` gray or ``3 * height * width`` RGB values 0..255) as a
    ``sensor_msgs/Image`` (``mono8`` or ``rgb8``)."""
    from sensor_msgs.msg import Image

    values = np.clip(np.rint(np.asarray(pixels, dtype=float).reshape(-1)), 0, 255)
    channels, left = divmod(len(values), width * height)
    if left or channels not in (1, 3):
        raise ValueError(f"{len(values)} values are no {width} x {height} gray or RGB image")
    return Image(header=header, height=height, width=width,
                 encoding="mono8" if channels == 1 else "rgb8", is_bigendian=0,
                 step=width * channels, data=values.astype(np.uint8).tobytes())
