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


def test_unknown_setting_lists_the_known_ones():
    with pytest.raises(ValueError, match=r"2link-0\.1-1"):
        get_setting("2link")
