"""``free_domain_id`` passes over a domain any of whose first participants
holds its RTPS metatraffic port on this host, whichever participant that is."""
import socket

import pytest

from sensorispace_ros.graph import dds_environment

from shared import free_domain_id


def _held(domain: int, participant: int) -> socket.socket:
    """A socket holding ``participant``'s metatraffic port of ``domain``, as Fast DDS does."""
    port = 7410 + 250 * domain + 2 * participant
    holder = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    holder.bind(("0.0.0.0", port))
    return holder


@pytest.mark.parametrize("participant", [0, 1, 7])
def test_a_domain_held_by_any_of_its_first_participants_is_not_free(participant):
    domain = free_domain_id()
    assert dds_environment.free_domain_id(domain) == domain
    with _held(domain, participant):
        assert dds_environment.free_domain_id(domain) != domain
    assert dds_environment.free_domain_id(domain) == domain
