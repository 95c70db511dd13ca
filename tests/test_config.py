import pytest

from masspush.config import EnvConfig, PhysicsConfig, default_pushes, physics_with


def test_defaults_are_the_papers():
    p = PhysicsConfig()
    assert p.friction_range == (0.5, 1.0)
    assert p.length_range == (0.1, 0.15)
    assert p.timestep == 0.001
    assert p.push_speed_max == 5.0
    assert p.push_steps == (5, 10)  # 5 ms ramp, then 10 steps of 1 ms held in contact
    assert default_pushes(2) == 2 and default_pushes(3) == 3
    assert EnvConfig(physics=PhysicsConfig(n_links=3)).pushes == 3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_links": 1}, "n_links"),
        ({"n_links": 2.5}, "n_links"),
        ({"mass_range": (1.0, 0.1)}, "mass_range is empty"),
        ({"mass_range": (-1.0, 1.0)}, "mass_range must be positive"),
        ({"mass_range": (0.0, 1.0)}, "mass_range must be positive"),
        ({"friction_range": (0.0, 1.0)}, "friction_range"),
        ({"length_range": (-0.1, 0.1)}, "length_range"),
        ({"timestep": 0.0}, "timestep"),
        ({"mass_range": (float("nan"), 1.0)}, "mass_range"),
        ({"init_joint_range": 2.0}, "init_joint_range"),
        ({"tool_friction": 0.0}, "tool_friction"),
    ],
)
def test_bad_physics_is_refused_with_the_value_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        PhysicsConfig(**kwargs)


def test_env_config_validation():
    with pytest.raises(ValueError, match="pushes"):
        EnvConfig(pushes=0)
    with pytest.raises(ValueError, match="obs_noise"):
        EnvConfig(obs_noise=-0.1)


def test_physics_with_rejects_unknown_fields():
    assert physics_with(n_links=3).n_links == 3
    with pytest.raises(ValueError, match="unknown physics parameter"):
        physics_with(mass=3)
