"""graph.framework.make_executor: what spins every node's process (private Context, own domain).

The graph relies on these properties of the executor (rclpy's EventsExecutor
by default): messages reach their callbacks in order, raw or not; timers -
also ones created while the node already spins (the agent's resume timer) -
run, cancelled ones do not; QoS events reach the contracts' handlers; a shut
down context ends ``spin_once`` with ExternalShutdownException (how run_node
stops on SIGTERM).
"""
import sys
import threading
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from std_msgs.msg import UInt64

from sensorispace_ros.graph.framework import make_executor


@pytest.fixture(params=["events", "single_threaded"])
def graph(request, domain_id):
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    talker = rclpy.create_node("executor_talker", context=context)
    listener = rclpy.create_node("executor_listener", context=context)
    executor, kind = make_executor(request.param, context=context)
    assert kind == request.param
    executor.add_node(listener)
    yield context, talker, listener, executor
    executor.shutdown()
    talker.destroy_node()
    listener.destroy_node()
    context.try_shutdown()


def _spin_until(executor, done, timeout_s=10.0):
    deadline = time.monotonic() + timeout_s
    while not done():
        assert time.monotonic() < deadline, "timed out"
        executor.spin_once(timeout_sec=0.05)


def test_the_default_is_rclpys_events_executor():
    executor, kind = make_executor()            # rclpy 7.1.6 (pinned) has it
    assert kind == "events"
    assert type(executor).__name__ == "EventsExecutor"
    assert not isinstance(executor, SingleThreadedExecutor)


def test_without_the_events_executor_it_falls_back(monkeypatch, domain_id):
    monkeypatch.setitem(sys.modules, "rclpy.experimental", None)    # import raises
    context = Context()
    rclpy.init(context=context, domain_id=domain_id,
               signal_handler_options=SignalHandlerOptions.NO)
    try:
        executor, kind = make_executor("events", context=context)
        assert kind == "single_threaded" and isinstance(executor, SingleThreadedExecutor)
        executor.shutdown()
    finally:
        context.try_shutdown()


def test_an_unknown_kind_is_refused():
    with pytest.raises(ValueError, match="executor: must be one of events, single_threaded"):
        make_executor("multi")


def test_messages_reach_their_callbacks_in_order_raw_or_not(graph):
    context, talker, listener, executor = graph
    got, raw = [], []
    listener.create_subscription(UInt64, "numbers", lambda m: got.append(m.data), 100)
    listener.create_subscription(UInt64, "numbers", raw.append, 100, raw=True)
    pub = talker.create_publisher(UInt64, "numbers", 100)
    _spin_until(executor, lambda: pub.get_subscription_count() == 2)
    for k in range(50):
        pub.publish(UInt64(data=k))
    _spin_until(executor, lambda: len(got) == 50 and len(raw) == 50)
    assert got == list(range(50))
    assert all(isinstance(r, bytes) for r in raw)
    assert [int.from_bytes(r[4:12], "little") for r in raw] == list(range(50))


def test_timers_run_also_when_created_later_and_cancelled_ones_do_not(graph):
    context, talker, listener, executor = graph
    executor.spin_once(timeout_sec=0.0)          # spinning before the timers exist
    ticks, cancelled = [], []
    listener.create_timer(0.02, lambda: ticks.append(time.monotonic()))
    stopped = listener.create_timer(0.02, lambda: cancelled.append(1))
    stopped.cancel()
    _spin_until(executor, lambda: len(ticks) >= 10, timeout_s=5.0)
    assert not cancelled
    assert ticks[-1] - ticks[0] < 0.6            # 9 periods: ~0.18 s


def test_a_shutdown_during_the_wait_ends_the_spin(graph):
    # rclpy's SIGTERM handler shuts the context down while run_node waits.
    context, talker, listener, executor = graph
    threading.Timer(0.2, context.try_shutdown).start()
    started = time.monotonic()
    with pytest.raises(ExternalShutdownException):
        executor.spin_once(timeout_sec=5.0)
    assert time.monotonic() - started < 2.0


def test_an_incompatible_qos_peer_is_reported(graph):
    # The contracts' QoS event handlers are waitables: served by the executor too.
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    context, talker, listener, executor = graph
    events = []
    listener.create_subscription(
        UInt64, "strict", lambda m: None,
        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE),
        event_callbacks=SubscriptionEventCallbacks(incompatible_qos=events.append,
                                                   use_default_callbacks=False))
    talker.create_publisher(UInt64, "strict",
                            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
    _spin_until(executor, lambda: events)
    assert events[0].total_count >= 1
