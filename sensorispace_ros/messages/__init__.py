"""The one place that converts numpy arrays <-> ROS messages (``clouds``:
tables and serialized clouds; ``joint_states``: joint states and the body's
description; ``viewer``: what viewers draw). The names below are the API.

Tables travel as ``sensor_msgs/PointCloud2`` used as a typed record batch
(msg_schemas/topics.yaml): height 1, width = rows, little-endian, dense, one
``PointField`` per column (count 1, packed offsets). Packing is
``array.array('B', table.tobytes())`` and unpacking ``np.frombuffer``, far
cheaper than assigning an ndarray to a sequence field.

Decoding is strict: anything that does not match the expected layout exactly
(names, types, offsets, steps, data length, non-finite floats, unknown joint
names) raises ``MessageError``; nodes log and drop such messages. A sensor's
columns (contract type ``number``: /body/sensation) may be any of
NUMBER_TYPES, one for all of them, and are read as float64; NaN in them is a
lost frame, inf is malformed.

The probe topics (/body/motor_command, /body/sensation, /body/sensor_pose,
/body/joint_states) and /environment/lights (one per change, which the agent
waits for) travel as serialized bytes both ways: ``CloudCdrPacker``
writes a cloud's CDR bytes for ``Publisher.publish(bytes)`` and
``cloud_from_cdr`` reads those of a ``raw=True`` subscription. rclpy's own
conversion of a PointCloud2 to and from Python objects costs more than the
rest of a round trip's work, and a graph run sends a command and an answer
for every ``sense`` call (docs/benchmarks.md). ``cloud_to_matrix`` /
``cloud_to_table`` check a ``SerializedCloud``
exactly as a PointCloud2, and rclpy reads the bytes written as the messages
``matrix_to_cloud`` / ``motor_to_joint_state`` build (tests/graph/test_messages.py
checks both ways with ``rclpy.serialization``; padding bytes are zero here,
unset in rclpy's). ``CloudCdrReader`` reads a float cloud's bytes as
``cloud_from_cdr`` + ``cloud_to_matrix`` do, and those laid out exactly as
``CloudCdrPacker`` writes them (the probe topics) by comparing them with the
contract's: half the cost, the same matrix or the same MessageError.

The body's description (``core.body_description.BodyDescription``) travels on
/body/description as a ``sensor_msgs/JointState``: ``name`` the joints,
``position`` their periods, frame id ``<unit>/<receptors>``
(``description_to_msg`` / ``description_from_msg``).
"""
from __future__ import annotations

from sensorispace_ros.messages.clouds import (CloudCdrPacker, CloudCdrReader, FloatCloud,
                                              HeaderView, MessageError, SerializedCloud, TimeView,
                                              cloud_column, cloud_from_cdr, cloud_to_matrix,
                                              cloud_to_table, make_header, matrix_to_cloud,
                                              NUMBER, NUMBER_TYPES, with_number_type,
                                              record_dtype, stamp_ns, table_to_cloud)
from sensorispace_ros.messages.joint_states import (MAX_JOINTS, MAX_RECEPTORS,
                                                    JointStateCdrPacker, description_from_msg,
                                                    description_to_msg, joint_state_to_motor,
                                                    motor_to_joint_state)
from sensorispace_ros.messages.viewer import (coloured_cloud, packed_rgb, pixels_to_image,
                                              shape_to_marker,
                                              shapes_to_marker_array, values_to_multiarray)

__all__ = ["CloudCdrPacker", "CloudCdrReader", "FloatCloud", "HeaderView", "MessageError",
           "SerializedCloud", "TimeView", "cloud_column", "cloud_from_cdr", "cloud_to_matrix",
           "cloud_to_table", "make_header", "matrix_to_cloud", "record_dtype", "stamp_ns",
           "table_to_cloud", "NUMBER", "NUMBER_TYPES", "with_number_type", "MAX_JOINTS", "MAX_RECEPTORS", "JointStateCdrPacker",
           "description_from_msg", "description_to_msg", "joint_state_to_motor",
           "motor_to_joint_state", "coloured_cloud", "packed_rgb", "shape_to_marker",
           "shapes_to_marker_array", "values_to_multiarray", "pixels_to_image"]
