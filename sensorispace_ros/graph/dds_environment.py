"""The environment the graph's processes run in: a private ROS domain,
localhost-only discovery, and the graph's Fast DDS profile.

``free_domain_id`` picks a domain no participant on this host uses yet.
``graph_environment`` is the children's environment; ``fastdds_profile_file``
writes the profile it names. The profile sets, for every participant and
writer of the graph:

- a short participant lease, so that a node killed with -9 is unmatched
  quickly: with Fast DDS's default 20 s lease a dead reader stays matched,
  never acknowledges, and a RELIABLE + KEEP_ALL writer to it fills its
  history until publish() fails;
- many quick initial announcements, so that a new node is seen soon (the
  environment starts the run when it sees every node);
- a frequent heartbeat of every reliable writer: a reader acknowledges what it
  received when the writer's heartbeat asks, and the agent's snapshot waits
  for its reactions to be acknowledged before it empties its journal.

No rclpy here: the launcher, which is not in the graph, imports it.
"""
from __future__ import annotations

import hashlib
import os
import socket
import tempfile
from pathlib import Path

# Fast DDS binds the unicast metatraffic port 7410 + 250 * domain + 2 * id for
# participant id of a domain (RTPS port mapping): a bound port = domain in use.
# Ids go to the lowest free port, so the first ones are probed: a graph whose
# first participant exited still holds the next.
_RTPS_PORT_BASE, _RTPS_DOMAIN_GAIN, _RTPS_PARTICIPANT_GAIN = 7410, 250, 2
_PROBED_PARTICIPANTS = 8

LEASE_DURATION_S = 3
LEASE_ANNOUNCEMENT_S = 1
HEARTBEAT_PERIOD_NS = 100_000_000
INITIAL_ANNOUNCEMENTS = 20
INITIAL_ANNOUNCEMENT_PERIOD_NS = 50_000_000
FASTDDS_PROFILE_XML = f"""<?xml version="1.0" encoding="UTF-8" ?>
<!-- written by sensorispace_ros.graph.dds_environment: short participant lease
     (a killed node is unmatched quickly), quick initial announcements (start-up),
     frequent writer heartbeats (acknowledgements the agent's snapshots wait for) -->
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <participant profile_name="sensorispace_graph" is_default_profile="true">
      <rtps>
        <builtin>
          <discovery_config>
            <leaseDuration><sec>{LEASE_DURATION_S}</sec></leaseDuration>
            <leaseAnnouncement><sec>{LEASE_ANNOUNCEMENT_S}</sec></leaseAnnouncement>
            <initialAnnouncements>
              <count>{INITIAL_ANNOUNCEMENTS}</count>
              <period><sec>0</sec><nanosec>{INITIAL_ANNOUNCEMENT_PERIOD_NS}</nanosec></period>
            </initialAnnouncements>
          </discovery_config>
        </builtin>
      </rtps>
    </participant>
    <data_writer profile_name="sensorispace_writer" is_default_profile="true">
      <times>
        <heartbeatPeriod><sec>0</sec><nanosec>{HEARTBEAT_PERIOD_NS}</nanosec></heartbeatPeriod>
      </times>
    </data_writer>
  </profiles>
</dds>
"""


def free_domain_id(start: int | None = None) -> int:
    """A ROS_DOMAIN_ID in 1..100 no participant on this host uses yet."""
    start = (os.getpid() % 100) + 1 if start is None else start
    for offset in range(100):
        domain = (start - 1 + offset) % 100 + 1
        if not any(_port_bound(_RTPS_PORT_BASE + _RTPS_DOMAIN_GAIN * domain +
                               _RTPS_PARTICIPANT_GAIN * participant)
                   for participant in range(_PROBED_PARTICIPANTS)):
            return domain
    raise RuntimeError("no free ROS_DOMAIN_ID in 1..100")


def _port_bound(port: int) -> bool:
    """Does a socket on this host hold UDP ``port``?"""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.bind(("127.0.0.1", port))
        except OSError:
            return True
    return False


def fastdds_profile_file(directory: str | Path | None = None) -> Path:
    """The graph's Fast DDS XML profile (a default participant profile with a short
    lease, a default writer profile with frequent heartbeats), written atomically
    once per content; Jazzy's Fast DDS 2.14 loads the
    file named by FASTRTPS_DEFAULT_PROFILES_FILE (not FASTDDS_...) and rmw_fastrtps
    creates every participant from the default participant profile."""
    directory = Path(directory or tempfile.gettempdir())
    digest = hashlib.sha256(FASTDDS_PROFILE_XML.encode()).hexdigest()[:12]
    path = directory / f"sensorispace_fastdds_{digest}.xml"
    if not path.is_file():
        directory.mkdir(parents=True, exist_ok=True)
        staging = path.with_name(f".{path.name}.{os.getpid()}")
        staging.write_text(FASTDDS_PROFILE_XML)
        os.replace(staging, path)
    return path


def graph_environment(domain_id: int, base: dict | None = None,
                      profile_dir: str | Path | None = None) -> dict:
    """The children's environment: private domain, localhost discovery unless the user
    chose a range, and the graph's Fast DDS profile unless the user set one."""
    env = dict(os.environ if base is None else base)
    env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if not env.get("FASTRTPS_DEFAULT_PROFILES_FILE"):
        env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(fastdds_profile_file(profile_dir))
    env["ROS_DOMAIN_ID"] = str(domain_id)
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (package_root, env.get("PYTHONPATH")) if p)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env
