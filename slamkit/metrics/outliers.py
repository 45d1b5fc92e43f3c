"""How well a robust back-end told false loop closures from true ones: outlier recall and
precision and inlier recall of its verdict (issue 16's Vertigo-style benchmark)."""

from __future__ import annotations

import numpy as np


def detection_scores(is_outlier: np.ndarray, inlier: np.ndarray) -> dict[str, float]:
    """Outlier recall and precision and inlier recall of a back-end's verdict (NaN where undefined)."""
    rejected = ~np.asarray(inlier, dtype=bool)
    out = np.asarray(is_outlier, dtype=bool)
    hits = int(np.count_nonzero(rejected & out))
    return {"outlier_recall": hits / out.sum() if out.any() else float("nan"),
            "outlier_precision": hits / rejected.sum() if rejected.any() else float("nan"),
            "inlier_recall": float(np.count_nonzero(~rejected & ~out) / max(int((~out).sum()), 1)),
            "outliers_rejected": float(hits), "inliers_rejected": float(np.count_nonzero(rejected & ~out))}
