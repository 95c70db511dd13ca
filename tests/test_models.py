import pytest

import masspush.models as models_module
from masspush.evaluate import EvaluateConfig
from masspush.learn.predictor import load_model
from masspush.models import SHIPPED_DIR, evaluate_model, resolve_model, shipped_file


def test_unknown_models_are_clear_errors(model_file, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="no model file"):
        resolve_model(tmp_path / "missing.pt", "2link-0.1-1")
    shipped = tmp_path / "models"
    (shipped / "2link-0.1-1").mkdir(parents=True)
    (shipped / "2link-0.1-1" / "rp.pt").write_bytes(b"")
    monkeypatch.setattr(models_module, "SHIPPED_DIR", shipped)
    with pytest.raises(ValueError, match=r"no shipped 'tp' model .*shipped for it: \['rp'\]"):
        resolve_model("tp", "2link-0.1-1")
    with pytest.raises(ValueError, match="trained for setting"):
        evaluate_model(EvaluateConfig("3link-0.1-1", str(model_file), episodes=2)).to_dict()


def test_every_shipped_model_loads_by_name_with_its_policy():
    from masspush.learn.policy import model_policy
    from masspush.learn.push_density import PUSH_DENSITY_FILE, load_push_density
    from masspush.learn.uncertainty import load_head
    from masspush.settings import KNOWN_SETTINGS, SETTINGS

    for name in SETTINGS:  # the paper's six: all four models of Table 1
        for model in ("rp", "rp+", "tp", "tp+"):
            assert (SHIPPED_DIR / name / f"{model}.pt").exists(), (name, model)
    for name in KNOWN_SETTINGS:
        for path in sorted((SHIPPED_DIR / name).glob("*.pt")):
            if path.name == PUSH_DENSITY_FILE:  # the filter's learned likelihood
                assert load_push_density(path).meta["setting"] == name
                continue
            if path.name.endswith(".dirichlet.pt"):  # fitted on the predictor it ships beside
                predictor, _ = load_model(path.with_name(path.name.replace(".dirichlet", "")))
                load_head(path, name, predictor)
                continue
            _, meta = load_model(resolve_model(path.stem, name), name)
            policy = model_policy(meta, path)  # a learned one loads its shipped policy file
            expected = "random" if path.stem.startswith("rp") else "learned"
            assert meta.get("policy", "random") == expected, (name, path.name)
            assert (policy.name == "random") == (expected == "random")


def test_a_model_of_another_setting_runs_only_when_allowed(tmp_path):
    other = str(shipped_file("2link-0.1-10", "rp"))
    with pytest.raises(ValueError, match=r"trained for setting '2link-0.1-10'.*--allow-mismatch"):
        evaluate_model(EvaluateConfig("2link-1-10", other, episodes=2))
    allowed = evaluate_model(EvaluateConfig("2link-1-10", other, episodes=4, allow_mismatch=True))
    assert allowed.setting == "2link-1-10" and allowed.episodes > 0
    with pytest.raises(ValueError, match=r"n_links 3, not 2$"):  # never across chain lengths
        three = str(shipped_file("3link-1-10", "rp"))
        evaluate_model(EvaluateConfig("2link-1-10", three, episodes=2, allow_mismatch=True))


@pytest.mark.slow
@pytest.mark.parametrize("name", ["real-ur10", "real-ur10-4push"])
def test_the_real_setups_learned_policy_keeps_the_chain_within_the_robots_reach(name):
    # The paper's UR10 stood still: each real setting's shipped policy, pushing with it (and
    # its speed governor), must keep the chain in reach on a fixed set of chains, for one
    # episode's pushes and over 8 runs in a row (docs/notebook/2026-12-02-reach-governor.md).
    from masspush.models import model_and_policy
    from masspush.real.backends import SimRobot
    from masspush.real.robot import run_segments
    from masspush.settings import get_setting
    from masspush.sim.simulate import REACH_FAILURES

    setting = get_setting(name)
    assert setting.pusher == "ur10-stationary"
    predictor, meta, policy = model_and_policy("tp+", name)
    assert meta["pusher"] == "ur10-stationary"
    k = setting.env_config().pushes
    for runs in (1, 8):
        robot = SimRobot(setting, seed=777, pushes=k * runs)
        lost = 0
        for _ in range(40):
            episode = run_segments(robot, predictor, policy, k, runs, seed=robot.seed)
            lost += episode.failure in REACH_FAILURES
        robot.close()
        assert lost <= 2, f"{lost} of 40 chains lost over {runs} run(s)"  # at most 5 %


def test_a_shipped_push_density_is_the_filter_s_default_likelihood():
    from masspush.models import load_estimator
    from masspush.settings import get_setting

    kuka = get_setting("2link-0.1-1")  # ships push-density.pt
    learned = load_estimator("bayes", kuka, progress=False)
    assert learned.config.likelihood == "learned" and learned.density is not None
    assert learned.config.density is None  # recorded as the shipped one
    simulated = load_estimator("bayes", kuka, bayes={"likelihood": "simulator"}, progress=False)
    assert simulated.config.likelihood == "simulator" and simulated.density is None
    # trained for the setting's pusher only: another pusher gets the simulator
    other = load_estimator("bayes-random", kuka, pusher="stiff", progress=False)
    assert other.config.likelihood == "simulator"
    real = load_estimator("bayes", get_setting("real-ur10"), progress=False)
    assert real.config.likelihood == "learned"
    assert real.density.placed  # a stationary robot's push depends on where the chain lies
    stiff = load_estimator("bayes", get_setting("2link-1-10"), progress=False)  # ships none
    assert stiff.config.likelihood == "simulator"
    with pytest.raises(ValueError, match="no shipped push density"):
        load_estimator("bayes", get_setting("2link-1-10"), bayes={"likelihood": "learned"})
