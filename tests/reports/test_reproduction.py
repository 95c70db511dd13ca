from types import SimpleNamespace

import pytest

import masspush.reports.reproduction as reproduce
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
        dir=tmp_path / "run",  # no state: nothing to record
        exports=lambda shipped_rp: {"tp": 1, "tp+": 2} | ({} if shipped_rp else {"rp": 0}),
    )
    assert ("rp" in reproduce.ship_recipe(run)) is ships_rp


def _fake_run(run_dir, tp_plus: float) -> None:
    """A finished run's directory: its state and one policy's PPO progress."""
    import json

    history = [
        {"stage": stage, "percentage_error": error, "constant_floor": 36.6}
        for stage, error in (("predictor-0", 20.0), ("predictor-1", 12.0),
                             ("predictor-final", tp_plus))
    ]  # fmt: skip
    timings = {"data-0": 60.0, "policy-1": 120.0, "evaluate-final": 6.0}
    config = {"meta_iterations": 1, "policy": {"steps": 1000}, "first_episodes": None,
              "final_episodes": None, "finetune": {"steps": 5000}}  # fmt: skip
    (run_dir / "policy-1").mkdir(parents=True)
    (run_dir / "policy-1" / "progress.csv").write_text(
        "timesteps,percentage_error,mean_reward,episodes\n512,15.0,7.0,100\n1024,13.0,7.2,100\n"
    )
    state = {"config": config, "timings": timings, "history": history}
    (run_dir / "state.json").write_text(json.dumps(state))


def test_the_table_outlives_the_run_directories(tmp_path):
    import shutil

    names, pushers = ["2link-0.1-1", "2link-1-10"], {"2link-0.1-1": "kuka", "2link-1-10": "stiff"}
    _fake_run(reproduce.train_dir("2link-0.1-1", "kuka", tmp_path), 9.5)
    _fake_run(reproduce.train_dir("2link-1-10", "stiff", tmp_path), 4.5)
    written = reproduce.write_outputs(names, pushers, root=tmp_path)
    assert reproduce.record_path("2link-0.1-1", "kuka", tmp_path) in written
    first = (tmp_path / "results" / "table1.md").read_text()
    # The bulky run directories go; the committed records give the same table and figures.
    shutil.rmtree(tmp_path / "runs")
    row = reproduce.collect_rows(names, pushers, tmp_path)[0]
    # A run from before the final stage's record took TP+ on first_episodes' worth (16k).
    assert row["tp+"] == 9.5 and row["recipe"] == "1 x 1k PPO, TP+ on 16k, 5k steps"
    reproduce.write_outputs(names, pushers, root=tmp_path)
    assert (tmp_path / "results" / "table1.md").read_text() == first
    # A setting with neither (a run from before the records) keeps its last row, marked.
    reproduce.record_path("2link-1-10", "stiff", tmp_path).unlink()
    rows = reproduce.collect_rows(names, pushers, tmp_path)
    assert rows[1]["tp+"] == 4.5 and rows[1]["carried"] and not rows[0].get("carried")
    assert "(carried over)" in reproduce.table_markdown(rows).splitlines()[3]
    # ... and a new run directory replaces it.
    _fake_run(reproduce.train_dir("2link-1-10", "stiff", tmp_path), 4.0)
    assert reproduce.collect_rows(names, pushers, tmp_path)[1]["tp+"] == 4.0
    times = (tmp_path / "results" / "recipe-times.md").read_text()
    shutil.rmtree(tmp_path / "runs")
    reproduce.write_outputs(names, pushers, root=tmp_path)  # 2link-1-10: no run, no record
    assert (tmp_path / "results" / "recipe-times.md").read_text() == times
