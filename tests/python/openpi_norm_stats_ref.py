"""Independent numpy computation of openpi's normalization statistics.

Usage: openpi_norm_stats_ref.py ZARR_PATH HORIZON

Reads state and action per episode from a replay buffer, rounds them to float32 (as
datasets store them), and feeds them to a RunningStats written from openpi's
normalize.py semantics: one update per episode, running mean / mean of squares, 5000-bin
histograms over [min - 1e-10, max + 1e-10] re-binned by np.histogram of the old left
edges when min/max grow, quantile = edges[searchsorted(cumsum, q * count)]. Actions are
taken over chunks of HORIZON frames, the last frame repeated past the end.
Prints {"state": {...}, "actions": {...}}.
"""

import json
import sys

import numpy as np
import zarr

BINS = 5000


class Running:
    def __init__(self):
        self.count = 0

    def update(self, batch):
        n = batch.shape[0]
        if self.count == 0:
            self.mean = batch.mean(axis=0)
            self.mean_sq = (batch**2).mean(axis=0)
            self.min = batch.min(axis=0)
            self.max = batch.max(axis=0)
            self.hist = [np.zeros(BINS) for _ in range(batch.shape[1])]
            self.edges = [np.linspace(self.min[i] - 1e-10, self.max[i] + 1e-10, BINS + 1) for i in range(batch.shape[1])]
        else:
            new_max, new_min = batch.max(axis=0), batch.min(axis=0)
            changed = np.any(new_max > self.max) or np.any(new_min < self.min)
            self.max = np.maximum(self.max, new_max)
            self.min = np.minimum(self.min, new_min)
            if changed:
                for i in range(len(self.hist)):
                    edges = np.linspace(self.min[i] - 1e-10, self.max[i] + 1e-10, BINS + 1)
                    self.hist[i], _ = np.histogram(self.edges[i][:-1], bins=edges, weights=self.hist[i])
                    self.edges[i] = edges
        self.count += n
        self.mean += (batch.mean(axis=0) - self.mean) * (n / self.count)
        self.mean_sq += ((batch**2).mean(axis=0) - self.mean_sq) * (n / self.count)
        for i in range(batch.shape[1]):
            h, _ = np.histogram(batch[:, i], bins=self.edges[i])
            self.hist[i] += h

    def stats(self):
        std = np.sqrt(np.maximum(0, self.mean_sq - self.mean**2))
        q = {}
        for name, p in (("q01", 0.01), ("q99", 0.99)):
            q[name] = [float(e[np.searchsorted(np.cumsum(h), p * self.count)]) for h, e in zip(self.hist, self.edges)]
        return {"mean": self.mean.tolist(), "std": std.tolist(), **q}


path, horizon = sys.argv[1], int(sys.argv[2])
root = zarr.open(path, "r")
ends = root["meta/episode_ends"][:]
state = root["data/state"][:].astype(np.float32).astype(np.float64)
action = root["data/action"][:].astype(np.float32).astype(np.float64)
s, a = Running(), Running()
start = 0
for end in ends:
    s.update(state[start:end])
    ep = action[start:end]
    idx = np.minimum(np.arange(len(ep))[:, None] + np.arange(horizon)[None, :], len(ep) - 1)
    a.update(ep[idx].reshape(-1, ep.shape[1]))
    start = end
print(json.dumps({"state": s.stats(), "actions": a.stats()}))
