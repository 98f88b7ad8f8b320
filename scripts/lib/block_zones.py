#!/usr/bin/env python3
"""PSNR in the blocks' overlap zones (ground points inside two or more
blocks' margined cells) and over the rest (scripts/blocks_benchmark.sh):

- held-out: the held-out captures' renders against the clean truth, a pixel
  in the zones when its ground point is; the flight's own held-out captures
  and the novel views between its captures (synth --novel-views) apart;
  beside the runs, two model-free references in the same pixels: the noisy capture itself and the clean
  truth blurred by a 3x3 box (a model that is exact but loses fine detail),
  and the share of plant pixels (truth NDVI > 0.4) in each, with the zones'
  PSNR at the rest's plant share (`zone_at_rest_mix`: the zones' plant and
  soil errors weighed as the rest's), and the PSNR over each cell's ground
  outside the zones (`cell_rest_db`: where one block's model alone draws
  the merged model, so a block that trained worse than its neighbours
  shows there);
- ortho (when every run has renders/ortho/reflectance.tif and the flight
  its truth/ortho.npy): the orthomosaic, sampled bilinearly at the truth
  ortho's pixel centres, against it over the ground every run covers, which
  weighs every point of the ground once; the same over the interior only
  (the ground under the flight lines: inside the camera centres' box, away
  from the flight's edges, which few captures see); and by distance from
  the nearest border between two cells (where the blocks are joined).

    block_zones.py SCENE BLOCKS RUN [RUN ...]

SCENE: the partitioned scene (transforms.json, clean/; the flight's
synth.json one folder up); BLOCKS: the partition (blocks.json); each RUN: a
run whose renders/test/*.npy were written by `ddhgs render RUN --format
npy` (and renders/ortho by `ddhgs render RUN --ortho`). Prints one JSON line
per run and reference.
"""
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

PLANT_NDVI = 0.4
BORDER_BINS_M = [(0, 0.2), (0.2, 0.6), (0.6, 1.5), (1.5, math.inf)]


def ground_uv(blocks, points):
    """Ground coordinates (u, v) of world points [..., 3]."""
    g = blocks["ground"]
    p = points - np.array(g["origin"])
    return p @ np.array(g["u"]), p @ np.array(g["v"])


def in_zone(blocks, u, v):
    count = np.zeros(u.shape, dtype=np.int32)
    for b in blocks["blocks"]:
        m = b["margined"]
        count += (u >= m["u"][0]) & (u <= m["u"][1]) & (v >= m["v"][0]) & (v <= m["v"][1])
    return count >= 2


def border_distance(blocks, u, v):
    """Distance on the ground to the nearest border between two cells."""
    inner_u = sorted({b["cell"]["u"][0] for b in blocks["blocks"] if b["col"] > 0})
    inner_v = sorted({b["cell"]["v"][0] for b in blocks["blocks"] if b["row"] > 0})
    d = np.full(u.shape, np.inf)
    for x in inner_u:
        d = np.minimum(d, np.abs(u - x))
    for y in inner_v:
        d = np.minimum(d, np.abs(v - y))
    return d


def view_ground(scene, blocks, name):
    """Ground coordinates (u, v) where each pixel's ray meets the ground plane."""
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
    return ground_uv(blocks, centre + d * t[..., None])


def cell_rest(blocks, u, v, zone):
    """Per block, the pixels whose ground lies in its cell outside every zone
    (zone: in_zone of the same u, v)."""
    return [~zone & (u >= b["cell"]["u"][0]) & (u <= b["cell"]["u"][1]) &
            (v >= b["cell"]["v"][0]) & (v <= b["cell"]["v"][1]) for b in blocks["blocks"]]


def psnr(squared_errors):
    mse = float(np.mean(squared_errors)) if squared_errors.size else float("nan")
    return round(-10 * math.log10(mse), 3) if mse > 0 else float("inf")


def plants(cube):
    red, nir = cube[..., 2], cube[..., 4]
    return (nir - red) / np.maximum(nir + red, 1e-9) > PLANT_NDVI


def box3(cube):
    h, w = cube.shape[:2]
    p = np.pad(cube, ((1, 1), (1, 1), (0, 0)), mode="edge")
    return sum(p[1 + a:1 + a + h, 1 + b:1 + b + w] for a in (-1, 0, 1) for b in (-1, 0, 1)) / 9


def zone_figures(error, zone, plant):
    rest_plants = float(plant[~zone].mean())
    mixed = rest_plants * error[zone & plant].mean() + (1 - rest_plants) * error[zone & ~plant].mean()
    return {"zone_db": psnr(error[zone]), "rest_db": psnr(error[~zone]),
            "gap_db": round(psnr(error[zone]) - psnr(error[~zone]), 3),
            "zone_at_rest_mix_db": psnr(np.array([mixed]))}


def held_out(scene_dir, scene, blocks, runs):
    """The held-out views' figures: the flight's own held-out captures
    (`held_out` lines) and, when the scene has them (synth --novel-views),
    the novel views between the flight's captures (`novel` lines), apart."""
    folder = os.path.join(runs[0], "renders", "test")
    names = sorted(f[:-4] for f in os.listdir(folder) if f.endswith(".npy"))
    groups = [("held_out", [n for n in names if not n.startswith("NOVEL_")]),
              ("novel", [n for n in names if n.startswith("NOVEL_")])]
    for label, group in groups:
        if group:
            held_out_group(scene_dir, scene, blocks, runs, label, group)


def held_out_group(scene_dir, scene, blocks, runs, label, names):
    errors = {r: [] for r in runs + ["noisy capture", "truth, 3x3 box"]}
    zones, plant, cells = [], [], []
    for name in names:
        truth = np.load(os.path.join(scene_dir, "clean", name + ".npy")).astype(np.float64)
        u, v = view_ground(scene, blocks, name)
        zone = in_zone(blocks, u, v)
        zones.append(zone.ravel())
        cells.append(np.stack([c.ravel() for c in cell_rest(blocks, u, v, zone)]))
        plant.append(plants(truth).ravel())
        images = {"noisy capture": np.load(os.path.join(scene_dir, "hyperspectral", name + ".npy")),
                  "truth, 3x3 box": box3(truth)}
        for run in runs:
            images[run] = np.load(os.path.join(run, "renders", "test", name + ".npy"))
        for key, image in images.items():
            errors[key].append(((image.astype(np.float64) - truth) ** 2).mean(-1).ravel())
    zone, plant = np.concatenate(zones), np.concatenate(plant)
    print(json.dumps({label + "_views": len(names), "zone_pixels": int(zone.sum()),
                      "rest_pixels": int((~zone).sum()),
                      "plant_share_zone": round(float(plant[zone].mean()), 3),
                      "plant_share_rest": round(float(plant[~zone].mean()), 3)}))
    cells = np.concatenate(cells, 1)
    for key, e in errors.items():
        e = np.concatenate(e)
        # Each cell's own ground away from the zones: where one block's
        # model alone draws the merged model.
        by_cell = {b["name"]: psnr(e[cells[i]]) for i, b in enumerate(blocks["blocks"])}
        print(json.dumps({label: key, "all_db": psnr(e), **zone_figures(e, zone, plant),
                          "cell_rest_db": by_cell}))


def read_geotiff(path):
    """Bands [B, H, W], geotransform and nodata of a GeoTIFF, read through gdal_translate."""
    info = json.loads(subprocess.run(["gdalinfo", "-json", path], check=True,
                                     capture_output=True, text=True).stdout)
    w, h = info["size"]
    bands = len(info["bands"])
    with tempfile.TemporaryDirectory() as tmp:
        raw = os.path.join(tmp, "bands.raw")
        subprocess.run(["gdal_translate", "-q", "-of", "ENVI", "-co", "INTERLEAVE=BSQ",
                        "-ot", "Float32", path, raw], check=True)
        data = np.fromfile(raw, dtype="<f4").reshape(bands, h, w).astype(np.float64)
    return data, info["geoTransform"], info["bands"][0].get("noDataValue")


def ortho(flight, scene, blocks, runs):
    synth = json.load(open(os.path.join(flight, "synth.json")))
    truth = np.load(os.path.join(flight, synth["ortho"]["file"])).astype(np.float64)
    gt = synth["ortho"]["geotransform"]
    e0, n0, _ = synth["georeference"]["world_origin_crs_m"]
    h, w = truth.shape[:2]
    cols, rows = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    east, north = gt[0] + cols * gt[1], gt[3] + rows * gt[5]
    # The synthetic world's x and y are easting and northing from the origin.
    world = np.stack([east - e0, north - n0, np.zeros_like(east)], -1)
    u, v = ground_uv(blocks, world)
    zone, border = in_zone(blocks, u, v), border_distance(blocks, u, v)
    cu, cv = ground_uv(blocks, np.array([np.array(f["transform_matrix"])[:3, 3]
                                         for f in scene["frames"]]))
    interior = (u >= cu.min()) & (u <= cu.max()) & (v >= cv.min()) & (v <= cv.max())
    covered = np.ones(zone.shape, dtype=bool)
    images = {}
    for run in runs:
        data, t, nodata = read_geotiff(os.path.join(run, "renders", "ortho", "reflectance.tif"))
        c, r = (east - t[0]) / t[1] - 0.5, (north - t[3]) / t[5] - 0.5
        inside = (c >= 0) & (r >= 0) & (c <= data.shape[2] - 1) & (r <= data.shape[1] - 1)
        c0 = np.clip(np.floor(c).astype(int), 0, data.shape[2] - 2)
        r0 = np.clip(np.floor(r).astype(int), 0, data.shape[1] - 2)
        fc, fr = np.clip(c - c0, 0, 1), np.clip(r - r0, 0, 1)
        image = 0
        for dr, dc, weight in [(0, 0, (1 - fr) * (1 - fc)), (0, 1, (1 - fr) * fc),
                               (1, 0, fr * (1 - fc)), (1, 1, fr * fc)]:
            s = data[:, r0 + dr, c0 + dc]
            inside &= s[0] != nodata
            image = image + s * weight
        covered &= inside
        images[run] = np.moveaxis(image, 0, -1)
    images["truth, 3x3 box"] = box3(truth)
    plant = plants(truth)
    print(json.dumps({"ortho_pixels_covered_by_every_run": int(covered.sum()),
                      "of_the_truth": int(covered.size),
                      "zone_share": round(float(zone[covered].mean()), 3),
                      "plant_share_zone": round(float(plant[covered & zone].mean()), 3),
                      "plant_share_rest": round(float(plant[covered & ~zone].mean()), 3)}))
    for key, image in images.items():
        e = ((image - truth) ** 2).mean(-1)[covered]
        figures = zone_figures(e, zone[covered], plant[covered])
        inner = interior[covered]
        figures["interior"] = zone_figures(e[inner], zone[covered][inner], plant[covered][inner])
        figures["by_border_distance_db"] = {
            f"{lo}-{hi} m": psnr(e[(border[covered] >= lo) & (border[covered] < hi)])
            for lo, hi in BORDER_BINS_M}
        print(json.dumps({"ortho": key, **figures}))


def main():
    scene_dir, blocks_dir, runs = sys.argv[1], sys.argv[2], sys.argv[3:]
    scene = json.load(open(os.path.join(scene_dir, "transforms.json")))
    blocks = json.load(open(os.path.join(blocks_dir, "blocks.json")))
    held_out(scene_dir, scene, blocks, runs)
    flight = os.path.dirname(os.path.abspath(scene_dir))
    if os.path.exists(os.path.join(flight, "truth", "ortho.npy")) and all(
            os.path.exists(os.path.join(r, "renders", "ortho", "reflectance.tif")) for r in runs):
        ortho(flight, scene, blocks, runs)


if __name__ == "__main__":
    main()
