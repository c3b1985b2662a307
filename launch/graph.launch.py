"""``ros2 launch sensorispace_ros graph.launch.py``: the graph, one process per node.

What ``sensorispace launch`` (graph/launcher.py) starts, for a ROS 2 install:
environment, body, agent, representation, (``record:=true``) the recorder and
(``view_port:=N``) the viewer, each with the run's parameter file (default: the
package's config/paper.yaml) and the same ``graph.*`` parameters. Discovery is localhost-only unless
ROS_AUTOMATIC_DISCOVERY_RANGE is set; the domain id is a free one unless
``domain_id:=N``; the graph's Fast DDS profile is used unless
FASTRTPS_DEFAULT_PROFILES_FILE names another. The launch ends when the
representation has written ``<results_dir>/<run>`` (and the recorder holds the
whole run) or when a node fails. Metrics from the bag:
``sensorispace analyze <bags_dir>/<run>``.

  ros2 launch sensorispace_ros graph.launch.py run:=seed0
  ros2 launch sensorispace_ros graph.launch.py config:=my.yaml record:=false domain_id:=42
  ros2 launch sensorispace_ros graph.launch.py view_port:=8765   # + the viewer, live in Foxglove
  ros2 launch sensorispace_ros graph.launch.py body:=false record:=false  # your body, node own_body

With ``body:=false`` the simulated body is left out and a body of your own
(docs/own-body.md), started by you, takes its place; the environment waits
for its node, named by ``body_node:=`` (default ``own_body``).
"""
import asyncio
import os
import shutil
import time
from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, LogInfo, OpaqueCoroutine, OpaqueFunction,
                            RegisterEventHandler, SetEnvironmentVariable, Shutdown)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown as ShutdownEvent
from launch_ros.actions import Node

from sensorispace_ros.graph.dds_environment import free_domain_id, graph_environment
from sensorispace_ros.graph.launcher import RECORDING_WAIT_S
from sensorispace_ros.recording.completeness import marker_path

PACKAGE = 'sensorispace_ros'
CONFIG_FILE = 'paper.yaml'
# what graph_environment sets for the graph's processes (PYTHONPATH: the sourced workspace's)
GRAPH_ENVIRONMENT = ('ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE',
                     'FASTRTPS_DEFAULT_PROFILES_FILE', 'PYTHONUNBUFFERED')


def generate_launch_description():
    default_config = os.path.join(get_package_share_directory(PACKAGE), 'config', CONFIG_FILE)
    return LaunchDescription([
        DeclareLaunchArgument('config', default_value=default_config,
                              description='ROS parameter file of the run'),
        DeclareLaunchArgument('run', default_value='',
                              description='run name (default: graph-<date>-<time>)'),
        DeclareLaunchArgument('results_dir', default_value='results',
                              description='results root: the run writes <results_dir>/<run>'),
        DeclareLaunchArgument('bags_dir', default_value='bags',
                              description='bag root: the recorder writes <bags_dir>/<run>'),
        DeclareLaunchArgument('record', default_value='true',
                              description='start the recorder (true|false)'),
        DeclareLaunchArgument('domain_id', default_value='',
                              description='ROS_DOMAIN_ID (default: a free one in 1..100)'),
        DeclareLaunchArgument('body', default_value='true',
                              description='start the simulated body (false: a body of your '
                                          'own takes its place, docs/own-body.md)'),
        DeclareLaunchArgument('body_node', default_value='own_body',
                              description='with body:=false, the node name of your body'),
        DeclareLaunchArgument('view_port', default_value='0',
                              description='start the viewer, serving the run to the Foxglove '
                                          'app on ws://127.0.0.1:<port> (0: no viewer)'),
        OpaqueFunction(function=graph),
    ])


def graph(context):
    """The nodes and their environment, once the launch arguments are known."""
    arg = context.launch_configurations
    record = arg['record'].strip().lower() in ('true', '1', 'yes')
    simulated_body = arg['body'].strip().lower() in ('true', '1', 'yes')
    run = arg['run'] or time.strftime('graph-%Y%m%d-%H%M%S')
    results = Path(arg['results_dir']) / run
    bag = Path(arg['bags_dir']) / run
    checkpoints = results / 'checkpoints'
    # a fresh run: what an earlier run of the same name persisted must not be resumed
    shutil.rmtree(checkpoints, ignore_errors=True)
    try:
        domain_id = int(arg['domain_id']) if arg['domain_id'] else free_domain_id()
    except ValueError:
        raise ValueError(f"domain_id: must be an integer, got {arg['domain_id']!r}") from None
    config = arg['config']
    # The representation's exit ends the launch; the others are stopped then.
    own = {'graph.results_dir': str(results), 'graph.checkpoint_dir': str(checkpoints),
           'graph.exit_when_done': False}
    try:
        view_port = int(arg['view_port'])
    except ValueError:
        raise ValueError(f"view_port: must be an integer, got {arg['view_port']!r}") from None
    body = 'body' if simulated_body else arg['body_node']
    waited_for = ([body, 'agent', 'representation'] + (['recorder'] if record else [])
                  + (['viewer'] if view_port else []))

    nodes = [
        Node(package=PACKAGE, executable='environment', output='screen',
             parameters=[config, {**own, 'graph.wait_for_nodes': waited_for}]),
        Node(package=PACKAGE, executable='agent', output='screen',
             parameters=[config, own]),
        Node(package=PACKAGE, executable='representation', output='screen',
             parameters=[config, {**own, 'graph.exit_when_done': True}]),
    ]
    if simulated_body:
        nodes.append(Node(package=PACKAGE, executable='body', output='screen',
                          parameters=[config, own]))
    if record:
        nodes.append(Node(package=PACKAGE, executable='recorder', output='screen',
                          parameters=[config, {'bag_path': str(bag)}]))
    if view_port:
        nodes.append(Node(package=PACKAGE, executable='viewer', output='screen',
                          parameters=[config, {'graph.view_port': view_port}]))
    env = graph_environment(domain_id)
    return [
        *(SetEnvironmentVariable(key, env[key]) for key in GRAPH_ENVIRONMENT),
        LogInfo(msg=f'run {run}: ROS_DOMAIN_ID={domain_id}, config {config}, results {results}'
                    + (f', bag {bag}' if record else ', not recording')),
        *nodes,
        *(RegisterEventHandler(OnProcessExit(target_action=node,
                                             on_exit=exit_handler(bag if record else None)))
          for node in nodes),
    ]


def exit_handler(bag):
    """What a node's exit means: the run's end once the representation exits 0
    (after the recorder holds the whole run), a failed run for any other exit."""
    def on_exit(event, context):
        if context.is_shutdown:
            return None
        name, code = event.action.node_executable, event.returncode
        if name != 'representation' or code != 0:
            return [Shutdown(reason=f'node {name!r} exited with code {code}')]
        if bag is None:
            return [Shutdown(reason='run finished')]
        return [OpaqueCoroutine(coroutine=shutdown_once_recorded, args=[bag])]
    return on_exit


async def shutdown_once_recorded(context, bag):
    """Shut down once the recorder has marked the run complete, at most RECORDING_WAIT_S."""
    marker = marker_path(bag)
    deadline = time.monotonic() + RECORDING_WAIT_S
    while not marker.exists() and time.monotonic() < deadline:
        await asyncio.sleep(0.05)
    reason = ('run finished and recorded' if marker.exists() else
              f'run finished; the recorder does not hold the whole run after '
              f'{RECORDING_WAIT_S:.0f} s: `sensorispace analyze {bag}` may lack points of view')
    await context.emit_event(ShutdownEvent(reason=reason))
