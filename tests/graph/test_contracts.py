"""contracts.py: topics sized by the body take their columns, elements and
joint names from the body description, and only from it."""
import pytest

from sensorispace_ros import contracts
from sensorispace_ros.core.body_description import BodyDescription

PAPER_BODY = BodyDescription.revolute(4, 6)
SMALL_BODY = BodyDescription(("hip", "knee"), "deg", (360.0, 360.0), 3)
SIZED_BY_THE_BODY = {"/body/description", "/body/motor_command", "/body/hold", "/body/sensation",
                     "/body/joint_states", "/agent/points_of_view",
                     "/agent/compensation_records", "/viewer/sensation"}


def test_exactly_the_body_topics_are_sized_by_the_description():
    described = {name for name, c in contracts.load_contracts().items() if c.described}
    assert described == SIZED_BY_THE_BODY


@pytest.mark.parametrize("topic", sorted(SIZED_BY_THE_BODY))
def test_a_topic_sized_by_the_body_has_no_layout_without_a_description(topic):
    spec = contracts.contract(topic)
    with pytest.raises(contracts.ContractError, match="description"):
        if spec.column_spec:
            spec.columns
        elif spec.element_spec:
            spec.elements
        else:
            spec.joint_names_for(None)


def test_the_paper_body_gives_the_paper_columns():
    def columns(topic):
        return list(contracts.contract(topic).columns_for(PAPER_BODY))

    assert columns("/body/motor_command") == ["m0", "m1", "m2", "m3"]
    assert columns("/body/sensation") == ["s0", "s1", "s2", "s3", "s4", "s5"]
    assert columns("/agent/points_of_view") == ["pov", "sample", "m0", "m1", "m2", "m3"]
    assert columns("/agent/compensation_records") == [
        "event", "anchor_event", "pov", "searched", "m0", "m1", "m2", "m3",
        "a0", "a1", "a2", "a3"]
    assert contracts.contract("/viewer/sensation").elements_for(PAPER_BODY) == \
        ("s0", "s1", "s2", "s3", "s4", "s5")
    for topic in ("/body/joint_states", "/body/description"):
        assert contracts.contract(topic).joint_names_for(PAPER_BODY) == \
            ("joint1", "joint2", "joint3", "joint4")


def test_a_hold_is_one_row_of_the_motor_state_and_its_band():
    assert list(contracts.contract("/body/hold").columns_for(SMALL_BODY)) == [
        "m0", "m1", "low0", "low1", "low2", "high0", "high1", "high2"]


def test_another_body_gives_its_own_columns():
    spec = contracts.contract("/agent/compensation_records").columns_for(SMALL_BODY)
    assert list(spec)[4:] == ["m0", "m1", "a0", "a1"]
    assert all(spec[n] == "float64" for n in ("m0", "m1", "a0", "a1"))
    assert list(contracts.contract("/body/sensation").columns_for(SMALL_BODY)) == \
        ["s0", "s1", "s2"]
    assert contracts.contract("/body/joint_states").joint_names_for(SMALL_BODY) == \
        ("hip", "knee")


def test_the_other_topics_keep_their_own_columns():
    for name, spec in contracts.load_contracts().items():
        if not spec.described:
            assert spec.columns == spec.column_spec == spec.columns_for(SMALL_BODY), name
            assert not any("<" in column for column in spec.columns), name


def test_the_description_topic_is_latched():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
    qos = contracts.contract("/body/description").qos
    assert (qos.reliability, qos.history, qos.depth, qos.durability) == (
        ReliabilityPolicy.RELIABLE, HistoryPolicy.KEEP_LAST, 1, DurabilityPolicy.TRANSIENT_LOCAL)
    assert contracts.contract("/body/description").type_name == "sensor_msgs/msg/JointState"
