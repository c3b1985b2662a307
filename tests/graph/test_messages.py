"""messages.py: numpy <-> ROS message round trips and strict rejections (no graph, fast)."""
import array
import struct

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState, PointCloud2, PointField

from sensorispace_ros import contracts, messages
from sensorispace_ros.core.body_description import BodyDescription
from sensorispace_ros.messages import MessageError, clouds

PAPER_BODY = BodyDescription.revolute(4, 6)       # joint1..joint4 in rad, 6 receptors
JOINT_NAMES = list(PAPER_BODY.joint_names)
MOTOR = contracts.contract("/body/motor_command").columns_for(PAPER_BODY)
POV = contracts.contract("/agent/points_of_view").columns_for(PAPER_BODY)
EVENT = contracts.contract("/environment/event").columns


def _wire(msg):
    """What a subscriber receives: the message after CDR serialisation."""
    return deserialize_message(serialize_message(msg), type(msg))


def test_matrix_round_trip_is_bit_exact_through_cdr():
    rng = np.random.default_rng(0)
    motor = rng.normal(size=(257, 4)) * 1e3
    header = messages.make_header("cmd/7", 123_456_789_012)
    msg = _wire(messages.matrix_to_cloud(motor, MOTOR, header))
    assert (msg.height, msg.width, msg.point_step, msg.row_step) == (1, 257, 32, 257 * 32)
    assert not msg.is_bigendian and msg.is_dense
    assert [f.name for f in msg.fields] == ["m0", "m1", "m2", "m3"]
    assert [f.offset for f in msg.fields] == [0, 8, 16, 24]
    back = messages.cloud_to_matrix(msg, MOTOR)
    assert back.dtype == np.float64 and np.array_equal(back, motor)
    assert msg.header.frame_id == "cmd/7" and messages.stamp_ns(msg.header) == 123_456_789_012


def test_mixed_type_table_round_trip_packed_layout():
    table = {"index": np.array([0, 1, 4_000_000_000], dtype=np.uint64),
             "kind": np.array([0, 1, 0]), "center_x": np.array([-6.0, 0.5, 6.0]),
             "center_y": np.array([1.0, 2.0, 3.0]), "grid_index": np.array([-1, 0, 3843])}
    msg = _wire(messages.table_to_cloud(table, EVENT, messages.make_header("change/1")))
    # uint32 + uint8 + 2 float64 + int32, packed without padding.
    assert [f.offset for f in msg.fields] == [0, 4, 5, 13, 21] and msg.point_step == 25
    assert [f.datatype for f in msg.fields] == [6, 2, 8, 8, 5]
    back = messages.cloud_to_table(msg, EVENT)
    for name, column in table.items():
        assert np.array_equal(back[name], column), name


def test_empty_table_round_trip():
    msg = _wire(messages.matrix_to_cloud(np.empty((0, 4)), MOTOR, messages.make_header("cmd/0")))
    assert messages.cloud_to_matrix(msg, MOTOR).shape == (0, 4)


def _valid_pov_cloud():
    rows = {"pov": np.repeat([0, 1], 3), "sample": np.tile([0, 1, 2], 2),
            "m0": np.zeros(6), "m1": np.ones(6), "m2": np.arange(6.0), "m3": -np.ones(6)}
    return messages.table_to_cloud(rows, POV, messages.make_header("change/3"))


def _tamper(**changes):
    msg = _valid_pov_cloud()
    for key, value in changes.items():
        if key == "fields":
            msg.fields = value(msg.fields)
        else:
            setattr(msg, key, value)
    return msg


def _renamed(fields):
    fields[2].name = "x"
    return fields


def _retyped(fields):
    fields[0].datatype = 5      # INT32 where UINT32 is expected
    return fields


def _shifted(fields):
    fields[3].offset += 1
    return fields


# One PointCloud2 wrong in one way each (also sent as serialized bytes below).
BAD_LAYOUTS = {
    "name": _tamper(fields=_renamed),
    "type": _tamper(fields=_retyped),
    "offset": _tamper(fields=_shifted),
    "missing": _tamper(fields=lambda f: f[:-1]),
    "point_step": _tamper(point_step=48),
    "row_step": _tamper(row_step=7),
    "width": _tamper(width=7),
    "height": _tamper(height=2),
    "bigendian": _tamper(is_bigendian=True),
    "short_data": _tamper(data=array.array("B", bytes(40 * 6 - 1))),
}


@pytest.mark.parametrize("bad", BAD_LAYOUTS.values(), ids=BAD_LAYOUTS.keys())
def test_layout_mismatch_rejected(bad):
    assert isinstance(bad, PointCloud2)
    with pytest.raises(MessageError):
        messages.cloud_to_table(_wire(bad), POV)


@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_non_finite_floats_rejected(value):
    motor = np.zeros((3, 4))
    motor[1, 2] = value
    with pytest.raises(MessageError, match="m2"):
        messages.cloud_to_matrix(_wire(messages.matrix_to_cloud(
            motor, MOTOR, messages.make_header("cmd/1"))), MOTOR)


def test_message_error_is_a_value_error():
    assert issubclass(MessageError, ValueError)


def test_joint_state_round_trip_and_rejections():
    motor = np.array([0.1, -1.5, 2.2, -3.0])
    msg = _wire(messages.motor_to_joint_state(motor, messages.make_header("cmd/2"), JOINT_NAMES))
    assert list(msg.name) == ["joint1", "joint2", "joint3", "joint4"]
    assert np.array_equal(messages.joint_state_to_motor(msg, JOINT_NAMES), motor)
    bad_names = JointState(name=["joint1", "joint2", "joint3", "elbow"], position=list(motor))
    short = JointState(name=JOINT_NAMES, position=[0.0, 1.0, 2.0])
    nan = JointState(name=JOINT_NAMES, position=[0.0, np.nan, 2.0, 3.0])
    bad_velocity = JointState(name=JOINT_NAMES, position=list(motor), velocity=[1.0])
    for bad in (bad_names, short, nan, bad_velocity):
        with pytest.raises(MessageError):
            messages.joint_state_to_motor(_wire(bad), JOINT_NAMES)


# ------------------------------------------------ the body description (/body/description)

@pytest.mark.parametrize("description", [
    PAPER_BODY, BodyDescription.revolute(2, 3, "deg"),
    BodyDescription(("shoulder", "elbow", "wrist"), "rad", (6.283185307179586, 3.0, 1e-3), 1)],
    ids=["paper", "deg", "named"])
def test_description_round_trip_through_cdr(description):
    msg = _wire(messages.description_to_msg(description, 42))
    assert msg.header.frame_id == f"{description.unit}/{description.receptors}"
    assert list(msg.name) == list(description.joint_names)
    assert list(msg.position) == list(description.periods)
    assert not len(msg.velocity) and not len(msg.effort)
    assert messages.description_from_msg(msg) == description


def test_the_paper_body_describes_itself_as_the_paper_columns():
    msg = messages.description_to_msg(PAPER_BODY)
    assert msg.header.frame_id == "rad/6" and msg.position.tolist() == [2 * np.pi] * 4
    assert list(MOTOR) == ["m0", "m1", "m2", "m3"]
    assert list(SENSATION) == [f"s{i}" for i in range(6)]
    assert contracts.contract("/body/joint_states").joint_names_for(PAPER_BODY) == \
        ("joint1", "joint2", "joint3", "joint4")


def _description(frame_id="deg/3", name=("a", "b"), position=(360.0, 360.0), **extra):
    return JointState(header=messages.make_header(frame_id), name=list(name),
                      position=list(position), **extra)


BAD_DESCRIPTIONS = {
    "no unit": _description("3"), "unknown unit": _description("grad/3"),
    "no receptors": _description("deg/"), "zero receptors": _description("deg/0"),
    "signed receptors": _description("deg/+3"), "huge receptors": _description("deg/99999999"),
    "too many receptors": _description(f"deg/{messages.MAX_RECEPTORS + 1}"),
    "superscript receptors": _description("deg/\u00b3"),
    "no joints": _description(name=(), position=()),
    "periods missing": _description(position=(360.0,)),
    "repeated names": _description(name=("a", "a")), "empty name": _description(name=("a", "")),
    "zero period": _description(position=(360.0, 0.0)),
    "negative period": _description(position=(-360.0, 360.0)),
    "nan period": _description(position=(360.0, np.nan)),
    "inf period": _description(position=(np.inf, 360.0)),
    "velocity": _description(velocity=[0.0, 0.0]), "effort": _description(effort=[1.0, 1.0]),
}


def test_a_well_formed_description_decodes():
    assert messages.description_from_msg(_wire(_description())) == \
        BodyDescription(("a", "b"), "deg", (360.0, 360.0), 3)


@pytest.mark.parametrize("bad", BAD_DESCRIPTIONS.values(), ids=BAD_DESCRIPTIONS.keys())
def test_a_malformed_description_is_a_message_error(bad):
    with pytest.raises(MessageError):
        messages.description_from_msg(_wire(bad))


def test_cloud_column_reads_one_column_whatever_the_others():
    for description in (PAPER_BODY, BodyDescription.revolute(2, 1), BodyDescription.revolute(9, 1)):
        columns = contracts.contract("/agent/points_of_view").columns_for(description)
        rows = {"pov": np.array([3, 3, 8]), "sample": np.array([0, 1, 0]),
                **{name: np.full(3, 0.5) for name in columns if name.startswith("m")}}
        msg = messages.table_to_cloud(rows, columns, messages.make_header("change/1"))
        for cloud in (_wire(msg), messages.cloud_from_cdr(serialize_message(msg))):
            assert messages.cloud_column(cloud, "pov", "uint32").tolist() == [3, 3, 8]
            assert messages.cloud_column(cloud, "m1", "float64").tolist() == [0.5] * 3
    empty = messages.table_to_cloud({name: [] for name in POV}, POV, messages.make_header("x"))
    assert messages.cloud_column(_wire(empty), "pov", "uint32").shape == (0,)
    # The layouts broken beyond the pov column (renamed, shifted or missing m
    # columns leave it readable).
    for name in ("type", "point_step", "row_step", "width", "height", "bigendian", "short_data"):
        with pytest.raises(MessageError):
            messages.cloud_column(_wire(BAD_LAYOUTS[name]), "pov", "uint32")
    with pytest.raises(MessageError, match="pov"):
        messages.cloud_column(_wire(_valid_pov_cloud()), "pov", "float64")


def test_encode_refuses_wrong_shapes():
    with pytest.raises(ValueError, match="shape"):
        messages.matrix_to_cloud(np.zeros((3, 5)), MOTOR, messages.make_header("cmd/0"))
    with pytest.raises(ValueError, match="lengths"):
        messages.table_to_cloud({"set": [1, 2], "pov_from": [1], "pov_to": [2, 3]},
                                contracts.contract("/agent/compensations").columns,
                                messages.make_header("x"))


# ------------------------------------------------ serialized clouds (raw publish / take)

# The simulated body's sensation columns by default (the contract's are ``number``).
SENSATION = messages.with_number_type(
    contracts.contract("/body/sensation").columns_for(PAPER_BODY), "float64")
POSE = contracts.contract("/body/sensor_pose").columns
# Every frame id length mod 4 (the padding after it) and mod 8 (JointState's float64s).
FRAME_IDS = ["", "c", "cm", "cmd", "cmd/", "cmd/7", "cmd/78", "cmd/789", "change/12345", "é/1"]


@pytest.mark.parametrize("columns", [MOTOR, SENSATION, POSE], ids=["motor", "sensation", "pose"])
def test_cdr_packer_writes_what_rclpy_reads_and_cloud_from_cdr_reads_what_rclpy_writes(columns):
    rng = np.random.default_rng(len(columns))
    packer = messages.CloudCdrPacker(columns)
    for rows in (0, 1, 2, 649):
        matrix = rng.normal(size=(rows, len(columns))) * 1e3
        for frame_id in FRAME_IDS:
            for stamp in (0, 123_456_789_012, 2**31 * 1_000_000_000 - 1):
                expected = messages.matrix_to_cloud(matrix, columns,
                                                    messages.make_header(frame_id, stamp))
                ours = packer.pack(matrix, frame_id, stamp)
                assert isinstance(ours, bytes)
                assert deserialize_message(ours, PointCloud2) == expected
                for raw in (ours, serialize_message(expected)):
                    cloud = messages.cloud_from_cdr(raw)
                    assert cloud.header.frame_id == frame_id
                    assert messages.stamp_ns(cloud.header) == stamp
                    back = messages.cloud_to_matrix(cloud, columns)
                    assert back.dtype == np.float64 and back.tobytes() == matrix.tobytes()
    with pytest.raises(ValueError, match="shape"):
        packer.pack(np.zeros((2, len(columns) + 1)), "cmd/1")
    with pytest.raises(ValueError, match="one type"):
        messages.CloudCdrPacker(EVENT)


NUMBER_SENSATION = contracts.contract("/body/sensation").columns_for(PAPER_BODY)


@pytest.mark.parametrize("kind", messages.NUMBER_TYPES)
def test_sensations_of_every_sensor_type_round_trip_as_float64(kind):
    # What a sensor of that type gives (integers for the integer types).
    rng = np.random.default_rng(3)
    dtype = np.dtype(kind)
    high = np.iinfo(dtype).max if dtype.kind == "u" else 1e3
    matrix = rng.uniform(0, high, (40, 6)).astype(dtype)
    if dtype.kind == "u":
        matrix[0] = [0, high, 1, high - 1, 2, 3]                 # the type's extremes
    typed = messages.with_number_type(NUMBER_SENSATION, kind)
    packed = messages.CloudCdrPacker(typed).pack(matrix, "cmd/4", 8)
    built = messages.matrix_to_cloud(matrix, typed, messages.make_header("cmd/4", 8))
    assert deserialize_message(packed, PointCloud2) == built
    assert {f.datatype for f in built.fields} == {getattr(PointField, kind.upper())}
    reader = messages.CloudCdrReader(NUMBER_SENSATION)
    assert reader.read_packed(packed) is not None                # the fast path takes it
    for back in (reader.read(packed).matrix, reader.read(serialize_message(built)).matrix,
                 messages.cloud_to_matrix(built, NUMBER_SENSATION)):
        assert back.dtype == np.float64
        assert back.tobytes() == matrix.astype(np.float64).tobytes()


def test_sensation_columns_must_share_one_number_type():
    rows = np.ones((2, 6))
    mixed = messages.table_to_cloud({name: rows[:, k] for k, name in enumerate(NUMBER_SENSATION)},
                                    {**dict.fromkeys(NUMBER_SENSATION, "float32"), "s5": "uint16"},
                                    messages.make_header("cmd/1"))
    with pytest.raises(MessageError, match="s5"):
        messages.cloud_to_matrix(mixed, NUMBER_SENSATION)
    for kind in ("int32", "uint32"):
        other = messages.matrix_to_cloud(rows, dict.fromkeys(NUMBER_SENSATION, kind),
                                         messages.make_header("cmd/1"))
        with pytest.raises(MessageError, match="'s0': datatype"):
            messages.cloud_to_matrix(other, NUMBER_SENSATION)
        assert messages.CloudCdrReader(NUMBER_SENSATION).read_packed(
            serialize_message(other)) is None
    with pytest.raises(ValueError, match="number column"):
        messages.with_number_type(NUMBER_SENSATION, "int32")


def test_joint_state_cdr_packer_writes_what_rclpy_reads():
    for names in (JOINT_NAMES, ["shoulder", "é"], [f"j{k}" for k in range(7)]):
        packer = messages.JointStateCdrPacker(names)
        motor = np.linspace(-3.0, 2.0, len(names))
        for frame_id in FRAME_IDS:
            expected = messages.motor_to_joint_state(motor, messages.make_header(frame_id, 7),
                                                     names)
            got = deserialize_message(packer.pack(motor, frame_id, 7), JointState)
            assert got == expected
            assert np.array_equal(messages.joint_state_to_motor(got, names), motor)
        with pytest.raises(ValueError, match="joints"):
            packer.pack(np.zeros(len(names) + 1), "cmd/1")


def test_mixed_type_table_through_serialized_bytes():
    table = {"index": np.array([0, 1, 4_000_000_000], dtype=np.uint64),
             "kind": np.array([0, 1, 0]), "center_x": np.array([-6.0, 0.5, 6.0]),
             "center_y": np.array([1.0, 2.0, 3.0]), "grid_index": np.array([-1, 0, 3843])}
    msg = messages.table_to_cloud(table, EVENT, messages.make_header("change/1"))
    records = messages.cloud_to_table(messages.cloud_from_cdr(serialize_message(msg)), EVENT)
    for name, values in table.items():
        assert np.array_equal(records[name], values), name


@pytest.mark.parametrize("bad", BAD_LAYOUTS.values(), ids=BAD_LAYOUTS.keys())
def test_layout_mismatch_rejected_from_serialized_bytes(bad):
    # The same contract checks as for a PointCloud2, with the same messages.
    with pytest.raises(MessageError) as from_message:
        messages.cloud_to_table(_wire(bad), POV)
    with pytest.raises(MessageError) as from_bytes:
        messages.cloud_to_table(messages.cloud_from_cdr(serialize_message(bad)), POV)
    assert str(from_bytes.value) == str(from_message.value)


def test_non_finite_floats_rejected_from_serialized_bytes():
    motor = np.zeros((3, 4))
    motor[2, 3] = np.nan
    raw = messages.CloudCdrPacker(MOTOR).pack(motor, "cmd/1")
    with pytest.raises(MessageError, match="m3"):
        messages.cloud_to_matrix(messages.cloud_from_cdr(raw), MOTOR)


def test_cloud_from_cdr_rejects_malformed_bytes_with_message_error_only():
    raw = messages.CloudCdrPacker(MOTOR).pack(np.ones((3, 4)), "cmd/12", 5)
    # Every truncation (the last byte, is_dense, is required).
    for length in range(len(raw)):
        with pytest.raises(MessageError):
            messages.cloud_from_cdr(raw[:length])
    with pytest.raises(MessageError, match="little-endian"):
        messages.cloud_from_cdr(b"\x00\x00\x00\x00" + raw[4:])       # big-endian CDR
    with pytest.raises(MessageError, match="bytes"):
        messages.cloud_from_cdr(np.frombuffer(raw, np.uint8))
    no_nul = bytearray(raw)
    no_nul[4 + 12 + 6] = ord("x")                                      # frame_id's NUL
    with pytest.raises(MessageError, match="frame_id"):
        messages.cloud_from_cdr(bytes(no_nul))
    bad_bool = bytearray(raw)
    bad_bool[-1] = 2                                                   # is_dense
    with pytest.raises(MessageError, match="bool"):
        messages.cloud_from_cdr(bytes(bad_bool))
    # Random corruption: a MessageError or a cloud, never another exception, and
    # whatever decodes passes or fails the contract check with a MessageError.
    rng = np.random.default_rng(3)
    decoded = 0
    for _ in range(3000):
        mutated = bytearray(raw)
        for where in rng.integers(0, len(raw), rng.integers(1, 4)):
            mutated[where] = rng.integers(0, 256)
        try:
            cloud = messages.cloud_from_cdr(bytes(mutated))
            messages.cloud_to_matrix(cloud, MOTOR)
            decoded += 1
        except MessageError:
            pass
    assert decoded > 0          # flips in the data or the padding still decode


# ------------------------------------------------ CloudCdrReader (fast path + general path)

MOTOR_FIELDS = tuple((name, 8 * j, 8, 1) for j, name in enumerate(MOTOR))   # FLOAT64 = 8
MOTOR_ROWS = np.arange(12.0).reshape(3, 4) - 5.5


def _packer_layout(frame_id=b"cmd/1", stamp=(0, 5), height=1, width=3, fields=MOTOR_FIELDS,
                   is_bigendian=0, point_step=32, row_step=96, data=MOTOR_ROWS.tobytes(),
                   n_data=None, is_dense=1, frame_padding=b"\x00", patch=(b"", b""),
                   cut=0):
    """Bytes laid out as CloudCdrPacker writes them, any member set to anything
    (frame_id as raw bytes; the packer's own bytes with the defaults); then the
    first ``patch[0]`` replaced with ``patch[1]``, and ``cut`` bytes cut off the end."""
    frame = struct.pack("<iII", *stamp, len(frame_id) + 1) + frame_id + b"\x00"
    frame += frame_padding * (-len(frame) % 4)
    return b"".join((b"\x00\x01\x00\x00", frame, struct.pack("<II", height, width),
                     clouds._cdr_fields(fields), bytes([is_bigendian, 0, 0, 0]),
                     struct.pack("<III", point_step, row_step,
                                 len(data) if n_data is None else n_data),
                     data, bytes([is_dense]))).replace(*patch, 1)[:-cut or None]


def _general(raw, columns=MOTOR):
    """What the general path makes of ``raw``: (frame_id, stamp_ns, matrix bytes) or
    the MessageError's text."""
    try:
        cloud = messages.cloud_from_cdr(raw)
        matrix = messages.cloud_to_matrix(cloud, columns)
    except MessageError as exc:
        return str(exc)
    return cloud.header.frame_id, messages.stamp_ns(cloud.header), matrix.tobytes()


def _read(reader, raw):
    try:
        cloud = reader.read(raw)
    except MessageError as exc:
        return str(exc)
    assert cloud.matrix.dtype == np.float64 and cloud.matrix.flags.writeable
    assert cloud.matrix.flags.c_contiguous and cloud.matrix.base is None    # the caller's
    return cloud.frame_id, cloud.stamp_ns, cloud.matrix.tobytes()


def _with_value(row, column, value):
    rows = MOTOR_ROWS.copy()
    rows[row, column] = value
    return rows.tobytes()


def _fields_with(index, **member):
    fields = [dict(zip(("name", "offset", "datatype", "count"), f)) for f in MOTOR_FIELDS]
    fields[index].update(member)
    return tuple(tuple(f.values()) for f in fields)


# Each breaks one thing the fast path checks (the rest as the packer writes it);
# the general path rejects every one of them.
PACKED_BAD = {
    "field_name": dict(fields=_fields_with(2, name="x")),
    "field_name_utf8": dict(patch=(b"m2\x00", b"\xff2\x00")),
    "field_type": dict(fields=_fields_with(0, datatype=7)),
    "field_offset": dict(fields=_fields_with(3, offset=25)),
    "field_count": dict(fields=_fields_with(1, count=2)),
    "field_missing": dict(fields=MOTOR_FIELDS[:-1]),
    "point_step": dict(point_step=48),
    "row_step": dict(row_step=7),
    "width": dict(width=7),
    "height": dict(height=2),
    "height_0": dict(height=0),
    "bigendian": dict(is_bigendian=1),
    "bigendian_bool": dict(is_bigendian=2),
    "dense_bool": dict(is_dense=2),
    "short_data": dict(data=MOTOR_ROWS.tobytes()[:-1]),
    "long_data": dict(data=MOTOR_ROWS.tobytes() + b"\x00"),
    "data_overrun": dict(n_data=97),
    # is_dense cut off, the data's last byte (a float's top byte) 0x01 as it would be
    "no_dense_last_data_byte_1": dict(data=MOTOR_ROWS.tobytes()[:-1] + b"\x01", cut=1),
    "frame_not_utf8": dict(frame_id=b"cmd/\xff"),
    **{f"{name}_{column}": dict(data=_with_value(1, j, value))
       for j, column in enumerate(MOTOR) for name, value in
       (("nan", np.nan), ("inf", np.inf), ("minus_inf", -np.inf))},
}
# Not as the packer writes them, yet within the contract: the general path's result.
PACKED_ACCEPTED = {
    "as_packed": {},
    "padding_after_frame_id": dict(frame_padding=b"\xab"),
    "not_dense": dict(is_dense=0),
    "empty_height_0": dict(height=0, width=0, row_step=0, data=b""),
    "empty": dict(width=0, row_step=0, data=b""),
    "negative_stamp": dict(stamp=(-3, 999_999_999)),
    "largest_floats": dict(data=np.full((3, 4), np.finfo(float).max).tobytes()),
}


def test_packer_layout_helper_writes_the_packers_bytes():
    # The variants below differ from the packer's output only where they say.
    assert _packer_layout() == messages.CloudCdrPacker(MOTOR).pack(MOTOR_ROWS, "cmd/1", 5)


@pytest.mark.parametrize("columns", [MOTOR, SENSATION, POSE], ids=["motor", "sensation", "pose"])
def test_cloud_reader_reads_what_the_general_path_reads_bit_for_bit(columns):
    rng = np.random.default_rng(7)
    reader, packer = messages.CloudCdrReader(columns), messages.CloudCdrPacker(columns)
    for rows in (0, 1, 5, 600):
        matrix = rng.normal(size=(rows, len(columns))) * 1e3
        matrix[0:1, 0] = -0.0                                    # sign of zero kept
        for frame_id in FRAME_IDS:
            for stamp in (0, 123_456_789_012, 2**31 * 1_000_000_000 - 1):
                ours = packer.pack(matrix, frame_id, stamp)
                theirs = serialize_message(messages.matrix_to_cloud(
                    matrix, columns, messages.make_header(frame_id, stamp)))
                # The packer's bytes take the fast path (else it is silently gone).
                assert reader.read_packed(ours) is not None
                for raw in (ours, theirs, bytearray(ours)):
                    expected = (frame_id, stamp, matrix.tobytes())
                    assert _general(raw, columns) == expected
                    assert _read(reader, raw) == expected
    with pytest.raises(ValueError, match="one type"):
        messages.CloudCdrReader(EVENT)


def test_cloud_reader_takes_the_fast_path_for_payloads_padded_as_between_processes():
    # Fast DDS hands a subscriber in another process the payload padded to a
    # multiple of 4 bytes (measured: 413 bytes published, 416 taken); a float
    # cloud's bytes end 1 past a multiple of 4 (is_dense), so 3 bytes are added.
    reader, packer = messages.CloudCdrReader(SENSATION), messages.CloudCdrPacker(SENSATION)
    for rows in (0, 1, 2, 5):
        for frame_id in ("cmd/1", "cmd/12", "change/3", "end/1234"):
            raw = packer.pack(np.arange(6.0 * rows).reshape(rows, 6), frame_id, 5)
            assert len(raw) % 4 == 1
            for padding in (1, 2, 3):
                padded = raw + b"\x00" * padding
                assert reader.read_packed(padded) is not None, (rows, frame_id, padding)
                assert _read(reader, padded) == _general(padded, SENSATION) \
                    == _read(reader, raw)
            # More than CDR's alignment pads: not the packer's layout; the general path.
            longer = raw + b"\x00" * 4
            assert reader.read_packed(longer) is None
            assert _read(reader, longer) == _general(longer, SENSATION)


def test_cloud_reader_result_is_a_copy():
    raw = messages.CloudCdrPacker(MOTOR).pack(MOTOR_ROWS, "cmd/1")
    reader = messages.CloudCdrReader(MOTOR)
    reader.read(raw).matrix[:] = 0.0
    assert np.array_equal(reader.read(raw).matrix, MOTOR_ROWS)


@pytest.mark.parametrize("changes", PACKED_BAD.values(), ids=PACKED_BAD.keys())
def test_cloud_reader_rejects_what_the_general_path_rejects_with_its_message(changes):
    raw = _packer_layout(**changes)
    expected = _general(raw)
    assert isinstance(expected, str), f"the general path accepts {changes}"
    assert messages.CloudCdrReader(MOTOR).read_packed(raw) is None
    assert _read(messages.CloudCdrReader(MOTOR), raw) == expected


@pytest.mark.parametrize("changes", PACKED_ACCEPTED.values(), ids=PACKED_ACCEPTED.keys())
def test_cloud_reader_accepts_what_the_general_path_accepts(changes):
    raw = _packer_layout(**changes)
    expected = _general(raw)
    assert not isinstance(expected, str), expected
    assert _read(messages.CloudCdrReader(MOTOR), raw) == expected


@pytest.mark.parametrize("bad", BAD_LAYOUTS.values(), ids=BAD_LAYOUTS.keys())
def test_cloud_reader_rejects_the_bad_layouts_as_the_general_path(bad):
    # BAD_LAYOUTS's tampering, on a cloud of float64 columns (the reader's kind).
    float_cloud = messages.matrix_to_cloud(np.ones((6, 6)), SENSATION,
                                           messages.make_header("cmd/3"))
    for key in ("point_step", "row_step", "width", "height", "is_bigendian", "data"):
        setattr(float_cloud, key, getattr(bad, key))
    float_cloud.fields = [f for f in bad.fields]
    raw = serialize_message(float_cloud)
    expected = _general(raw, SENSATION)
    assert isinstance(expected, str)
    assert _read(messages.CloudCdrReader(SENSATION), raw) == expected


def test_cloud_reader_on_malformed_bytes_says_what_the_general_path_says():
    raw = messages.CloudCdrPacker(MOTOR).pack(np.ones((3, 4)), "cmd/12", 5)
    reader = messages.CloudCdrReader(MOTOR)
    variants = [raw[:length] for length in range(len(raw))]            # every truncation
    variants += [b"\x00\x00\x00\x00" + raw[4:], raw + b"\x00", np.frombuffer(raw, np.uint8)]
    no_nul = bytearray(raw)
    no_nul[4 + 12 + 6] = ord("x")                                      # frame_id's NUL
    variants.append(bytes(no_nul))
    rng = np.random.default_rng(11)
    for _ in range(3000):                                              # random corruption
        mutated = bytearray(raw)
        for where in rng.integers(0, len(raw), rng.integers(1, 4)):
            mutated[where] = rng.integers(0, 256)
        variants.append(bytes(mutated))
    accepted = 0
    for variant in variants:
        expected = _general(variant)
        assert _read(reader, variant) == expected
        accepted += not isinstance(expected, str)
    assert 0 < accepted < len(variants)
