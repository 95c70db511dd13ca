"""Reports: the paper's baselines and Table 1 (`baselines`, `reproduce`), the Bayes table
(`bayes_table`), benchmarks (`bench`), the demo (`demo`) and videos (`render`).

The names below are its public API (what experiments/ may import)."""

from masspush._exports import lazy, names

EXPORTS = {
    "baselines": ("PAPER_TABLE", "run_baselines"),
    "reproduce": ("reproduce", "train_setting"),
    "bayes_table": ("bayes_table",),
    "demo": ("demo", "run_demo"),
    "render": ("render_episode",),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
