from types import SimpleNamespace

import pytest

import masspush.reports.reproduce as reproduce
from masspush.settings import get_setting


@pytest.mark.parametrize(
    ("shipped", "ships_rp"),
    [
        (None, True),  # no RP yet
        ({"pusher": "ur10-stationary", "setting": "same"}, False),  # this world's RP stays
        ({"pusher": "ur10", "setting": "same"}, True),  # another pusher's is replaced
        ({"pusher": "ur10-stationary", "setting": {"name": "real-ur10"}}, True),  # other physics
    ],
)
def test_a_recipe_ships_its_rp_where_the_shipped_one_is_of_another_world(
    shipped, ships_rp, tmp_path, monkeypatch
):
    setting = get_setting("real-ur10")
    rp = tmp_path / "rp.pt"
    if shipped is not None:
        rp.write_bytes(b"")
        meta = {**shipped, "setting": setting.as_dict() if shipped["setting"] == "same"
                else shipped["setting"]}  # fmt: skip
        monkeypatch.setattr(reproduce, "load_model", lambda path: (None, meta))
    monkeypatch.setattr(reproduce, "shipped_file", lambda name, model: rp)
    monkeypatch.setattr(reproduce, "ship", lambda name, sources: sorted(sources))
    run = SimpleNamespace(
        setting=setting,
        pusher="ur10-stationary",
        exports=lambda shipped_rp: {"tp": 1, "tp+": 2} | ({} if shipped_rp else {"rp": 0}),
    )
    assert ("rp" in reproduce.ship_recipe(run)) is ships_rp
