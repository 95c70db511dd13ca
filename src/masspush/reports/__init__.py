"""Reports: the paper's baselines and Table 1 (`baselines`, `reproduction`), the Bayes table
(`bayes_report`), benchmarks (`bench`), the demo (`demonstration`) and videos (`render`).

The names below are its public API (what experiments/ may import)."""

from masspush._exports import lazy, names

EXPORTS = {
    "baselines": ("PAPER_TABLE", "run_baselines"),
    "reproduction": ("reproduce", "train_setting"),
    "bayes_report": ("bayes_table",),
    "demonstration": ("demo", "run_demo"),
    "render": ("render_episode",),
}  # fmt: skip
__getattr__ = lazy(__name__, EXPORTS)
__all__ = names(EXPORTS)
