import masspush.reports.bayes_report as bayes_table_module
from masspush.reports.bayes_report import bayes_table, filter_settings


def fake_evaluate(calls):
    def run_model(setting, model, episodes, seed=0, per_episode=False, workers=None):
        calls.append((setting, model, episodes))
        result = {"percentage_error": 3.0 if model == "bayes" else 5.0, "coverage": 0.9,
                  "seconds_per_episode": 4.2, "episodes": episodes,
                  "filter": filter_settings(setting)}  # fmt: skip
        if per_episode or model == "bayes":
            # The filter failed on episode 0, TP+ on none; both off by 0.1 elsewhere.
            index = list(range(1 if model == "bayes" else 0, episodes))
            truth = [[0.5, 0.5]] * len(index)
            off = 0.1 if model == "bayes" else 0.2
            estimate = [[0.5 + off, 0.5 - off]] * len(index)
            result["per_episode"] = {"index": index, "estimate": estimate, "truth": truth}
        return result

    return run_model


def test_measurements_are_cached_and_the_table_built_from_them(tmp_path, monkeypatch):
    calls = []
    monkeypatch.setattr(bayes_table_module, "run_model", fake_evaluate(calls))
    text = bayes_table(["2link-1-10"], 7, root=tmp_path, tp_episodes=9)
    assert sorted(calls) == [
        ("2link-1-10", "bayes", 7), ("2link-1-10", "bayes-random", 7),
        ("2link-1-10", "tp+", 7), ("2link-1-10", "tp+", 9),
    ]  # fmt: skip
    # TP+ twice: Table 1's 9 episodes, and the filter's 7 for the paired column.
    assert (tmp_path / "results" / "bayes" / "2link-1-10-tp+-same-episodes.json").exists()
    # Paired on the 6 episodes both scored: MAE 0.1 and 0.2 over shares of 0.5 (+ 1e-4).
    # Every episode differs by the same, so does every bootstrap resample.
    row = ("| 2link-1-10 | 5.00 / 8.26 | **3.00** | 20.00 / 39.99 (6; -20.00 to -20.00) | 5.00 "
           "| 90 % / 90 % / 90 % |")  # fmt: skip
    assert row in text
    bayes_table(["2link-1-10"], 7, root=tmp_path, tp_episodes=9)  # all cached
    assert len(calls) == 4
    bayes_table(["2link-1-10"], 8, ["bayes"], root=tmp_path)  # another size: measured again
    assert calls[-1] == ("2link-1-10", "bayes", 8)
    # The filter's configuration changed since: the Bayesian cells are measured again.
    changed = {**filter_settings("2link-1-10"), "particles": 1}
    monkeypatch.setattr(bayes_table_module, "filter_settings", lambda setting: changed)
    before = len(calls)
    bayes_table(["2link-1-10"], 8, root=tmp_path, tp_episodes=9)
    assert calls[before:] == [("2link-1-10", "bayes", 8), ("2link-1-10", "bayes-random", 8),
                              ("2link-1-10", "tp+", 8)]  # fmt: skip
    assert (tmp_path / "results" / "bayes.md").read_text().count("| 2link-1-10 |") == 1
    # Measuring another setting keeps this one's cached row, in the paper's order.
    text = bayes_table(["2link-0.1-1"], 8, root=tmp_path, tp_episodes=9)
    assert calls[-1][0] == "2link-0.1-1" and "| 2link-1-10 |" in text
    assert text.index("| 2link-0.1-1 |") < text.index("| 2link-1-10 |")
    assert "3link" not in text  # nothing cached, not asked: no row


def test_table_only_reports_what_is_missing(tmp_path):
    text = bayes_table(["3link-0.1-1"], 5, root=tmp_path, measure_missing=False)
    assert "| 3link-0.1-1 | not yet / 12.02 | **not yet** |" in text


def test_a_measurement_from_before_the_arm_model_counts_only_where_it_still_holds(
    tmp_path, monkeypatch
):
    import json

    from masspush.reports.bayes_report import ADDED_SETTINGS, measure

    calls = []
    monkeypatch.setattr(bayes_table_module, "run_model", fake_evaluate(calls))
    # The stiff pusher's filter is what it was; where the KR 5 pushes, the filter now
    # simulates it instead of its surrogate.
    for setting, still_holds in (("2link-1-10", True), ("2link-0.1-1", False)):
        old = {k: v for k, v in filter_settings(setting).items() if k not in ADDED_SETTINGS}
        path = tmp_path / "results" / "bayes" / f"{setting}-bayes.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(
            json.dumps({"requested_episodes": 5, "filter": old, "old": True, "per_episode": {}})
        )
        before = len(calls)
        result = measure(setting, "bayes", 5, root=tmp_path)
        assert result.get("old", False) is still_holds
        assert len(calls) - before == (0 if still_holds else 1)


def test_a_filter_measurement_without_episodes_is_measured_again_for_pairing(tmp_path, monkeypatch):
    import json

    from masspush.reports.bayes_report import measure

    calls = []
    monkeypatch.setattr(bayes_table_module, "run_model", fake_evaluate(calls))
    path = tmp_path / "results" / "bayes" / "2link-1-10-bayes.json"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps({"requested_episodes": 5, "filter": filter_settings("2link-1-10")}))
    assert "per_episode" in measure("2link-1-10", "bayes", 5, root=tmp_path) and len(calls) == 1
    measure("2link-1-10", "bayes", 5, root=tmp_path)  # now cached with its episodes
    assert len(calls) == 1


def test_a_learned_models_measurement_is_redone_once_its_files_change(tmp_path, monkeypatch):
    from masspush.reports.bayes_report import measure

    calls = []
    monkeypatch.setattr(bayes_table_module, "run_model", fake_evaluate(calls))
    digest = {"value": "a"}
    monkeypatch.setattr(bayes_table_module, "model_files_digest", lambda s, m: digest["value"])
    measure("2link-1-10", "tp+", 5, root=tmp_path)
    measure("2link-1-10", "tp+", 5, root=tmp_path)
    assert len(calls) == 1
    digest["value"] = "b"  # retrained, or its head refitted
    measure("2link-1-10", "tp+", 5, root=tmp_path)
    assert len(calls) == 2


def test_the_model_files_digest_covers_predictor_policy_and_head(tmp_path, monkeypatch):
    import shutil

    import masspush.models as models_module
    from masspush.models import SHIPPED_DIR
    from masspush.reports.bayes_report import model_files_digest

    models = tmp_path / "models"
    shutil.copytree(SHIPPED_DIR / "2link-1-10", models / "2link-1-10")
    monkeypatch.setattr(models_module, "SHIPPED_DIR", models)
    seen = {model_files_digest("2link-1-10", "tp+")}
    for name in ("tp+.dirichlet.pt", "tp+.policy.zip", "tp+.pt"):
        path = models / "2link-1-10" / name
        path.write_bytes(path.read_bytes() + b"\0")
        seen.add(model_files_digest("2link-1-10", "tp+"))
    assert len(seen) == 4
