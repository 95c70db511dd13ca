"""Learning: the LSTM predictor (`predictor`), what the policy sees and earns (`features`),
the PPO policy (`policy`, `vec_env`), the predictor as an estimator (`estimator`), learned
uncertainty (`uncertainty`), the paper's alternating recipe (`recipe`) and the particle
filter's learned likelihood (`push_density`).

The names below are its public API (what experiments/ may import)."""

from masspush._exports import lazy, names

EXPORTS = {
    "predictor": ("FAST", "LOSSES", "MassPredictor", "Predictor", "PredictorEnsemble",
                  "TrainConfig", "load_model", "save_model", "step_inputs", "train_ensemble",
                  "train_predictor", "validation_split"),
    "features": ("history_dim", "history_features", "paper_reward"),
    "policy": ("LearnedPolicy", "PolicyConfig", "PushPolicyEnv", "model_policy", "train_policy"),
    "vec_env": ("BatchPushVecEnv",),
    "estimator": ("PredictorEstimator",),
    "uncertainty": ("HeadConfig", "LearnedPosterior", "calibrate"),
    "recipe": ("FINETUNE", "PREDICTOR", "Recipe", "RecipeConfig"),
    "push_density": ("DensityConfig", "PushDensity", "density_for", "load_push_density",
                     "train_push_density"),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
