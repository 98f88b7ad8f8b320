#!/usr/bin/env python3
"""PSNR of held-out renders against the clean truth, over the pixels whose
ground point lies in two or more blocks' margined cells (the overlap zones)
and over the rest (scripts/blocks_benchmark.sh).

    block_zones.py SCENE BLOCKS RUN [RUN ...]

SCENE: the partitioned scene (transforms.json, clean/); BLOCKS: the
partition (blocks.json); each RUN: a run whose renders/test/*.npy were
written by `ddhgs render RUN --format npy`. Prints one JSON line per run.
"""
import json
import math
import os
import sys

import numpy as np


def zone_masks(scene, blocks, name):
    frames = {os.path.splitext(os.path.basename(f["hyperspectral_file_path"]))[0]: f
              for f in scene["frames"]}
    f = frames[name]
    fx, fy = f.get("fl_x", scene.get("fl_x")), f.get("fl_y", scene.get("fl_y"))
    cx, cy = f.get("cx", scene.get("cx")), f.get("cy", scene.get("cy"))
    w, h = int(f.get("w", scene.get("w"))), int(f.get("h", scene.get("h")))
    c2w = np.array(f["transform_matrix"], dtype=np.float64)
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    # OpenGL camera axes: x right, y up, looking along -z.
    d = np.stack([(x - cx) / fx, -(y - cy) / fy, -np.ones_like(x)], -1) @ c2w[:3, :3].T
    g = blocks["ground"]
    origin, n = np.array(g["origin"]), np.array(g["normal"])
    centre = c2w[:3, 3]
    t = ((origin - centre) @ n) / (d @ n)
    p = centre + d * t[..., None] - origin
    u, v = p @ np.array(g["u"]), p @ np.array(g["v"])
    count = np.zeros_like(u, dtype=np.int32)
    for b in blocks["blocks"]:
        m = b["margined"]
        count += ((u >= m["u"][0]) & (u <= m["u"][1]) & (v >= m["v"][0]) & (v <= m["v"][1]))
    return count >= 2


def psnr(squared_errors):
    mse = float(np.mean(squared_errors)) if squared_errors.size else float("nan")
    return -10 * math.log10(mse) if mse > 0 else float("inf")


def main():
    scene_dir, blocks_dir, runs = sys.argv[1], sys.argv[2], sys.argv[3:]
    scene = json.load(open(os.path.join(scene_dir, "transforms.json")))
    blocks = json.load(open(os.path.join(blocks_dir, "blocks.json")))
    for run in runs:
        folder = os.path.join(run, "renders", "test")
        overlap, rest = [], []
        for file in sorted(os.listdir(folder)):
            if not file.endswith(".npy"):
                continue
            name = file[:-4]
            render = np.load(os.path.join(folder, file)).astype(np.float64)
            truth = np.load(os.path.join(scene_dir, "clean", file)).astype(np.float64)
            zone = zone_masks(scene, blocks, name)
            error = ((render - truth) ** 2).mean(-1)
            overlap.append(error[zone])
            rest.append(error[~zone])
        overlap, rest = np.concatenate(overlap), np.concatenate(rest)
        print(json.dumps({"run": run, "overlap_psnr_db": round(psnr(overlap), 3),
                          "rest_psnr_db": round(psnr(rest), 3),
                          "overlap_pixels": int(overlap.size), "rest_pixels": int(rest.size)}))


if __name__ == "__main__":
    main()
