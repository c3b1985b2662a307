"""``config.parse_overrides``: the ``--set KEY=VALUE`` texts of the bench scripts."""
import pytest

from sensorispace_ros.config import ConfigError, load_config, parse_overrides


def test_values_read_as_numbers_words_and_lists():
    parsed = parse_overrides(["world.retina.noise=1e-3", "world.grid_count=17",
                              "naive.chained_anchors=true", "world.clock=rows",
                              "mujoco.image=[8, 6]"])
    assert parsed == {"world.retina.noise": 1e-3, "world.grid_count": 17,
                      "naive.chained_anchors": True, "world.clock": "rows",
                      "mujoco.image": [8, 6]}
    assert type(parsed["world.grid_count"]) is int and type(parsed["world.retina.noise"]) is float


def test_parsed_overrides_reach_the_configuration():
    cfg = load_config(None, parse_overrides(["world.retina.noise=1e-3", "world.grid_count=17"]))
    assert cfg["world"]["retina"]["noise"] == 1e-3 and cfg["world"]["grid_count"] == 17


@pytest.mark.parametrize("item", ["world.grid_count", "=3"])
def test_an_override_without_key_or_value_is_named(item):
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_overrides([item])
