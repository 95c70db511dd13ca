import pytest

from masspush.settings import SETTINGS, get_setting


def test_the_six_paper_settings():
    assert list(SETTINGS) == [
        "2link-0.1-1",
        "2link-1-10",
        "2link-0.1-10",
        "3link-0.1-1",
        "3link-1-10",
        "3link-0.1-10",
    ]
    s = get_setting("3link-0.1-10")
    assert (s.n_links, s.mass_range) == (3, (0.1, 10.0))
    physics = s.physics()
    assert (physics.n_links, physics.mass_range) == (3, (0.1, 10.0))


def test_each_setting_names_its_pusher():
    # The torque-limited arm cannot move chains of 10 kg links (docs/results.md); in the
    # 3-link light cell the same arm stands farther back, for a longer run-up.
    assert {name: s.pusher for name, s in SETTINGS.items()} == {
        "2link-0.1-1": "kuka",
        "2link-1-10": "stiff",
        "2link-0.1-10": "stiff",
        "3link-0.1-1": "kuka-far",
        "3link-1-10": "stiff",
        "3link-0.1-10": "stiff",
    }


def test_the_real_setup_is_a_setting_of_its_own():
    # The paper's UR10 experiment: 2 links of 0.01-0.3 kg; not one of Table 1's six.
    s = get_setting("real-ur10")
    assert (s.n_links, s.mass_range, s.pusher) == (2, (0.01, 0.3), "ur10-stationary")
    assert "real-ur10" not in SETTINGS
    assert abs(s.physics().joint_limit - 1.5708) < 0.03


def test_a_settings_file_may_choose_the_pusher(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(
        "[a]\nlinks = 2\nmass_range = [1.0, 2.0]\n[b]\nlinks = 2\n"
        "mass_range = [1.0, 2.0]\npusher = 'ur10'\n"
    )
    assert (get_setting("a", path).pusher, get_setting("b", path).pusher) == ("kuka", "ur10")


def test_a_setting_may_choose_its_pushes_per_episode(tmp_path):
    assert get_setting("2link-0.1-1").env_config().pushes == 2  # the paper's K
    assert get_setting("3link-1-10").env_config().pushes == 3
    four = get_setting("real-ur10-4push")
    real = get_setting("real-ur10")
    assert (four.env_config().pushes, four.env_config().pusher, four.mass_range) == (
        4, "ur10-stationary", real.mass_range
    )  # fmt: skip
    assert four.overrides == real.overrides  # the same world, only more pushes
    assert four.env_config("stiff", obs_noise=0.0).pusher == "stiff"
    assert four.as_dict()["pushes"] == 4 and "pushes" not in get_setting("real-ur10").as_dict()
    path = tmp_path / "s.toml"
    path.write_text("[a]\nlinks = 3\nmass_range = [1.0, 2.0]\npushes = 5\n")
    assert get_setting("a", path).env_config().pushes == 5


def test_a_setting_comes_back_from_its_dict_with_its_physics(tmp_path):
    from masspush.settings import SETTINGS, Setting

    path = tmp_path / "s.toml"
    path.write_text("[real-ur10]\nlinks = 2\nmass_range = [0.01, 0.3]\ntool_friction = 0.5\n"
                    "friction_range = [0.4, 1.1]\npushes = 3\n")  # fmt: skip
    ours = get_setting("real-ur10", path)
    for setting in [*SETTINGS.values(), get_setting("real-ur10-4push"), ours]:
        back = Setting.from_dict(setting.as_dict())
        assert back.physics() == setting.physics() and back.pushes == setting.pushes
    assert Setting.from_dict(ours.as_dict()).physics().tool_friction == 0.5


def test_unknown_setting_lists_the_known_ones():
    with pytest.raises(ValueError, match=r"2link-0\.1-1"):
        get_setting("2link")


def test_custom_settings_from_a_toml_file(tmp_path):
    from masspush.settings import load_settings

    path = tmp_path / "settings.toml"
    path.write_text("[long4]\nlinks = 4\nmass_range = [1.0, 5.0]\nlength_range = [0.15, 0.2]\n")
    s = get_setting("long4", path)
    physics = s.physics()
    assert (physics.n_links, physics.mass_range, physics.length_range) == (
        4,
        (1.0, 5.0),
        (0.15, 0.2),
    )
    assert "2link-0.1-1" in {**load_settings(path), "2link-0.1-1": None}


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[bad]\nlinks = 1\nmass_range = [1.0, 2.0]\n", "n_links"),
        ("[bad]\nlinks = 2\nmass_range = [2.0, 1.0]\n", "empty"),
        ("[bad]\nlinks = 2\n", "lacks 'mass_range'"),
        ("[bad]\nlinks = 2\nmass_range = [1.0, 2.0]\nfriction = 3\n", "unknown parameter"),
        ("[bad\n", "not valid TOML"),
        ("[bad]\nlinks = 2\nmass_range = [1.0, 2.0]\npusher = 'panda'\n", "unknown pusher"),
        ("[bad]\nlinks = 2\nmass_range = [1.0, 2.0]\npushes = 0\n", "pushes"),
    ],
)
def test_invalid_settings_files_are_refused_with_the_reason(tmp_path, text, message):
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message):
        get_setting("bad", path)
