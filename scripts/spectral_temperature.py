#!/usr/bin/python3
"""Share of the spectral loss in the training gradient, per softmax temperature.

Usage: scripts/spectral_temperature.py RENDERS SCENE
  RENDERS: `ddhgs render RUN --split test --format npy --out RENDERS`
  SCENE:   the dataset folder (its hyperspectral/<view>.npy are the truth)

For each temperature T, prints the unweighted spectral loss and the ratio of
the gradient norms of w3 * L_spectral and w1 * L1 with respect to the render
(the loss re-implemented here in double precision, gradients by autograd).
"""
import glob
import os
import sys

import numpy as np
import torch

W1, W3 = 0.8, 0.1


def spectral(pred, gt, t, alpha=0.5, beta=0.5):
    lp = torch.log_softmax(pred / t, -1)
    lg = torch.log_softmax(gt / t, -1)
    kl = (lg.exp() * (lg - lp)).sum(-1)
    dp, dg = lp.exp(), lg.exp()
    cos = (dp * dg).sum(-1) / (dp.norm(dim=-1) * dg.norm(dim=-1))
    return (alpha * kl + beta * (1 - cos)).mean()


def truth(path):
    raw = np.load(path)
    scale = 65535.0 if raw.dtype == np.uint16 else 255.0 if raw.dtype == np.uint8 else 1.0
    return torch.tensor(raw.astype(np.float64) / scale)


def main(renders, scene):
    files = sorted(glob.glob(os.path.join(renders, "*.npy")))
    if not files:
        sys.exit(f"{renders}: no .npy renders (use ddhgs render --format npy)")
    print("T      L_spectral  |grad w3 L_spectral| / |grad w1 L1|")
    for t in [1.0, 0.3, 0.1, 0.03]:
        values, ratios = [], []
        for f in files:
            pred = torch.tensor(np.load(f), dtype=torch.float64).clamp(0, 1).requires_grad_(True)
            gt = truth(os.path.join(scene, "hyperspectral", os.path.basename(f)))
            (g1,) = torch.autograd.grad(W1 * (pred - gt).abs().mean(), pred)
            s = spectral(pred, gt, t)
            (gs,) = torch.autograd.grad(W3 * s, pred)
            values.append(s.item())
            ratios.append((gs.norm() / g1.norm()).item())
        print(f"{t:<6} {np.mean(values):.2e}    {np.mean(ratios):.4f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
