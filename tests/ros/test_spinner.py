"""nodes.SubscriptionSpinner: the graph's own spin_once (private Context, own domain)."""
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import UInt64

from sensorispace_ros.nodes import SubscriptionSpinner


@pytest.fixture
def graph(domain_id, monkeypatch):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    talker = rclpy.create_node("spinner_talker", context=context)
    listener = rclpy.create_node("spinner_listener", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(listener)
    spinner = SubscriptionSpinner(listener, executor)

    def no_executor(*args, **kwargs):
        raise AssertionError("the lean spinner ran the executor (lost wake-ups)")
    monkeypatch.setattr(executor, "spin_once", no_executor)
    yield context, talker, listener, spinner
    spinner.destroy()
    executor.shutdown()
    talker.destroy_node()
    listener.destroy_node()
    context.try_shutdown()


def _spin_until(spinner, done, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < deadline, "timed out"
        spinner.spin_once(0.05)


def test_messages_reach_their_callbacks_in_order_raw_or_not(graph):
    context, talker, listener, spinner = graph
    assert spinner.lean
    got, raw = [], []
    listener.create_subscription(UInt64, "numbers", lambda m: got.append(m.data), 100)
    listener.create_subscription(UInt64, "numbers", raw.append, 100, raw=True)
    pub = talker.create_publisher(UInt64, "numbers", 100)
    _spin_until(spinner, lambda: pub.get_subscription_count() == 2)
    for k in range(50):
        pub.publish(UInt64(data=k))
    _spin_until(spinner, lambda: len(got) == 50 and len(raw) == 50)
    assert got == list(range(50))
    assert all(isinstance(r, bytes) for r in raw)
    assert [int.from_bytes(r[4:12], "little") for r in raw] == list(range(50))


def test_timers_run_and_cancelled_ones_do_not(graph):
    context, talker, listener, spinner = graph
    ticks, cancelled = [], []
    listener.create_timer(0.02, lambda: ticks.append(time.monotonic()))
    stopped = listener.create_timer(0.02, lambda: cancelled.append(1))
    stopped.cancel()
    # A ready timer wakes the spinner's wait (9 periods: ~0.18 s).
    _spin_until(spinner, lambda: len(ticks) >= 10, timeout_s=5.0)
    assert not cancelled
    assert ticks[-1] - ticks[0] < 0.6


def test_a_subscription_created_later_is_served(graph):
    context, talker, listener, spinner = graph
    spinner.spin_once(0.0)                      # wait set built without it
    got = []
    listener.create_subscription(UInt64, "late", lambda m: got.append(m.data), 10)
    pub = talker.create_publisher(UInt64, "late", 10)
    _spin_until(spinner, lambda: pub.get_subscription_count() == 1)
    pub.publish(UInt64(data=7))
    _spin_until(spinner, lambda: got == [7])


def test_a_shut_down_context_ends_the_spin(graph):
    context, talker, listener, spinner = graph
    context.try_shutdown()
    with pytest.raises(ExternalShutdownException):
        spinner.spin_once(0.01)


def test_without_the_wait_set_binding_it_is_the_executor(graph, monkeypatch):
    # (also the path of a node holding a waitable that is not a QoS event handler)
    context, talker, listener, spinner = graph
    spinner.lean = False
    calls = []
    monkeypatch.setattr(spinner.executor, "spin_once",
                        lambda timeout_sec=None: calls.append(timeout_sec))
    spinner.spin_once(0.3)
    assert calls == [0.3]


def test_an_incompatible_qos_peer_is_reported(graph):
    # The contracts' QoS event handlers are waitables: served by the spinner too.
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    context, talker, listener, spinner = graph
    events = []
    listener.create_subscription(
        UInt64, "strict", lambda m: None,
        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
        event_callbacks=SubscriptionEventCallbacks(incompatible_qos=events.append,
                                                   use_default_callbacks=False))
    talker.create_publisher(UInt64, "strict",
                            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    _spin_until(spinner, lambda: events)
    assert events[0].total_count >= 1
