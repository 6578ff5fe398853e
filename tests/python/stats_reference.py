"""Reference values for the stats stage, from SciPy, scikit-learn and NumPy.

Usage:
  stats_reference.py tables <in.json>   # [{"counts": [[...], ...]}, ...] -> measures per table
  stats_reference.py columns <in.json>  # {"name": [[row], ...], ...} -> openpi-style stats per column

Prints JSON on stdout. The Rust tests compare their own results with these.
"""

import json
import sys

import numpy as np
from scipy.spatial.distance import jensenshannon
from scipy.stats import chi2_contingency
from sklearn.metrics import normalized_mutual_info_score


def measures(counts):
    table = np.asarray(counts, dtype=np.int64)
    out = {}
    # Chi-square on the table without all-zero rows and columns (SciPy refuses zero
    # expected counts), Pearson's statistic without continuity correction.
    reduced = table[table.sum(axis=1) > 0][:, table.sum(axis=0) > 0]
    if reduced.shape[0] >= 2 and reduced.shape[1] >= 2:
        res = chi2_contingency(reduced, correction=False)
        out["chi2"] = {"statistic": float(res.statistic), "p_value": float(res.pvalue), "dof": int(res.dof)}
    else:
        out["chi2"] = None
    # NMI on the expanded labels: one (row, column) pair per counted observation.
    cells = np.arange(table.size)
    rows = np.repeat(cells // table.shape[1], table.ravel())
    cols = np.repeat(cells % table.shape[1], table.ravel())
    out["nmi"] = float(normalized_mutual_info_score(rows, cols, average_method="arithmetic"))
    # Squared Jensen-Shannon distance between every pair of rows with mass.
    pairs = []
    for a in range(table.shape[0]):
        for b in range(a + 1, table.shape[0]):
            if table[a].sum() == 0 or table[b].sum() == 0:
                continue
            p, q = table[a].astype(float), table[b].astype(float)
            pairs.append(
                {
                    "a": a,
                    "b": b,
                    "base2": float(jensenshannon(p, q, base=2) ** 2),
                    "base_e": float(jensenshannon(p, q) ** 2),
                }
            )
    out["js"] = pairs
    return out


def columns(arrays):
    out = {}
    for name, rows in arrays.items():
        x = np.asarray(rows, dtype=np.float64)
        out[name] = {
            "mean": x.mean(axis=0).tolist(),
            "std": x.std(axis=0).tolist(),
            "min": x.min(axis=0).tolist(),
            "max": x.max(axis=0).tolist(),
            "q01": np.quantile(x, 0.01, axis=0).tolist(),
            "q99": np.quantile(x, 0.99, axis=0).tolist(),
        }
    return out


def main():
    mode, path = sys.argv[1], sys.argv[2]
    with open(path) as f:
        data = json.load(f)
    if mode == "tables":
        result = [measures(t["counts"]) for t in data]
    elif mode == "columns":
        result = columns(data)
    else:
        raise SystemExit(f"unknown mode {mode}")
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main()
