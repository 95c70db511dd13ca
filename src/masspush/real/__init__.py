"""The real-robot path: the robot interface (`robot`) and its backends (`backends`), a session
through a robot (`session`), the classifier fine-tuned on real episodes (`classifier`,
`classifier_jobs`) and the particle filter's push density tuned to a lab (`density_tuning`)
with its reading of the table's friction (`table_friction`), the
sim-to-real test world (`target_world`, `transfer`) and domain
randomisation (`randomisation`, `robot_env`), a stationary robot's speed governor fitted to a
lab's pushes (`governor`), and the particle filter as an arm of the protocol (`filter_arm`).

The names below are its public API (what experiments/ may import); those of the 0.1 module
`masspush.robot` are among them (`masspush.robot` itself still imports, as this package)."""

from masspush._exports import lazy, names

EXPORTS = {
    "robot": ("EstimationEpisode", "GeometryWarning", "PushReport", "RestPose", "Robot",
              "check_geometry", "fmt", "model_geometry", "model_physics", "model_speed_reader",
              "print_push", "run_estimation", "run_segments", "speed_reader"),
    "backends": ("BACKENDS", "RecordedPolicy", "ReplayMismatchError", "ReplayRobot", "SimRobot",
                 "make_robot"),
    "session": ("SessionConfig", "run_session"),
    "classifier": ("PAPER_CLASSES", "ClassifierConfig", "classifier_inputs", "cross_validate",
                   "episode_log_probs", "fit_classifier", "labelled", "out_of_fold_log_probs",
                   "predictor_features", "start_pose_control", "start_pose_features",
                   "stratified_folds"),
    "classifier_jobs": (
        "ClassifyJob", "FinetuneJob", "TuneDensityJob", "check_recording_fits", "classify",
        "classify_by_posterior", "finetune", "read_with_predictor", "tune",
    ),
    "density_tuning": ("CalibrationWarning", "LabelledPush", "TuneConfig",
                       "check_calibration_length", "class_log_likelihoods", "class_masses",
                       "cross_validate_tuning", "evidence_per_push", "first_pushes",
                       "friction_grid",
                       "joint_log_likelihoods", "labelled_pushes", "push_ladder",
                       "posterior_accuracy", "posterior_classes", "pushes_per_episode",
                       "record_tuning", "score_posterior", "sort_over", "sorting_evidence",
                       "sorting_grid", "tune_density", "SortingEvidence", "class_posterior",
                       "true_class_evidence", "tuned_classes"),
    "table_friction": ("DRIFT_LIMIT", "FrictionDriftWarning", "FrictionReading",
                       "calibration_friction", "check_drift", "friction_lines",
                       "friction_profiles", "pool_reading", "read_friction"),
    "target_world": ("TRAINING_KNOBS", "Lab", "TargetWorld", "TargetWorldRobot", "WorldRanges",
                     "scaled_world"),
    "transfer": ("ARMS", "FEATURE_KINDS", "FEATURE_NAMES", "Sim2RealConfig", "Sim2RealJob",
                 "arm_feature_kinds", "class_episodes", "class_robot", "episode_id",
                 "paired_answers", "paired_test",
                 "plot_accuracy_by_pushes", "read_summary", "record_arm", "record_classes",
                 "run_sim2real",
                 "score_arm", "sign_test", "sim2real"),
    "randomisation": ("RandomiseConfig", "RandomiseRun", "randomise", "run_randomised"),
    "robot_env": ("RobotEnv",),
    "governor": ("episode_pushes", "fit_governor", "fitted_setting_governor", "recording_pushes"),
    "filter_arm": ("FilterArm",),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
