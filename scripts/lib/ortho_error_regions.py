#!/usr/bin/env python3
"""Where an orthomosaic of the synthetic nadir strip differs from the truth's
orthographic reflectance (docs/benchmarks.md, the orthomosaic section).

    ortho_error_regions.py STRIP ORTHO.tif [--disc-radius 1.6] [--plant-radius 0.45]

STRIP: a `synth --preset rig-nadir` folder (synth.json, truth/ortho.npy);
ORTHO.tif: `render RUN --ortho` of a run trained on it, read through GDAL
(gdalinfo, gdal_translate). Compares the mosaic, sampled bilinearly at the
truth's pixel centres (exact pixels when the grids share their edges), over
the pixels it covers: PSNR (peak 1) over all of them and per region (the
plant's zone around the origin, the ground disc, its edge, the targets of
--gcp-targets, pixels within 3 px of nodata), each region's share of the
squared error, per band PSNR and mean error (bias), and the ground's PSNR
after averaging both over 2x2 and 4x4 pixels (how much of its error is
pixel-scale detail). Standard library only.
"""
import argparse
import array
import json
import math
import os
import struct
import subprocess
import tempfile


def read_npy(path):
    with open(path, "rb") as f:
        f.read(8)
        (header_len,) = struct.unpack("<H", f.read(2))
        header = f.read(header_len).decode()
        assert "'<f4'" in header, header
        values = array.array("f")
        values.frombytes(f.read())
    return values


def read_tif(path):
    info = json.loads(subprocess.run(["gdalinfo", "-json", path], check=True,
                                     capture_output=True, text=True).stdout)
    with tempfile.TemporaryDirectory() as tmp:
        raw = os.path.join(tmp, "mosaic.raw")
        subprocess.run(["gdal_translate", "-q", "-of", "ENVI", "-co", "INTERLEAVE=BSQ",
                        "-ot", "Float32", path, raw], check=True)
        values = array.array("f")
        with open(raw, "rb") as f:
            values.frombytes(f.read())
    return info["geoTransform"], info["size"][0], info["size"][1], len(info["bands"]), values


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("strip")
    parser.add_argument("ortho")
    parser.add_argument("--disc-radius", type=float, default=1.6)
    parser.add_argument("--plant-radius", type=float, default=0.45)
    a = parser.parse_args()
    synth = json.load(open(os.path.join(a.strip, "synth.json")))
    tgt = synth["ortho"]["geotransform"]
    th, tw = synth["ortho"]["height"], synth["ortho"]["width"]
    origin = synth["georeference"]["world_origin_crs_m"]
    truth = read_npy(os.path.join(a.strip, "truth", "ortho.npy"))
    gt, mw, mh, nb, mosaic = read_tif(a.ortho)
    targets = synth["ground_control_points"] if "gcp_targets" in synth else []
    half_target = synth["gcp_targets"]["side_m"] / 2 + 0.5 * tgt[1] if targets else 0

    def at(b, row, col):
        return mosaic[(b * mh + row) * mw + col]

    def sample(b, east, north):
        x = (east - gt[0]) / gt[1] - 0.5
        y = (north - gt[3]) / gt[5] - 0.5
        x0, y0 = math.floor(x), math.floor(y)
        if x0 < 0 or y0 < 0 or x0 + 1 >= mw or y0 + 1 >= mh:
            return None
        fx, fy = x - x0, y - y0
        value = 0.0
        for dy in (0, 1):
            for dx in (0, 1):
                p = at(b, y0 + dy, x0 + dx)
                if p == -9999:
                    return None
                value += p * (fx if dx else 1 - fx) * (fy if dy else 1 - fy)
        return value

    regions = {}
    diffs = {}  # (row, col) -> per-band difference, ground pixels only
    for row in range(th):
        for col in range(tw):
            east = tgt[0] + (col + 0.5) * tgt[1]
            north = tgt[3] + (row + 0.5) * tgt[5]
            values = [sample(b, east, north) for b in range(nb)]
            if any(v is None for v in values):
                continue
            r = math.hypot(east - origin[0], north - origin[1])
            if any(abs(east - p["easting_m"]) < half_target and
                   abs(north - p["northing_m"]) < half_target for p in targets):
                key = "target"
            elif abs(r - a.disc_radius) < 0.06:
                key = "disc edge"
            elif r > a.disc_radius:
                key = "outside the disc"
            elif r < a.plant_radius:
                key = "plant zone"
            else:
                key = "ground"
            x, y = int((east - gt[0]) / gt[1]), int((north - gt[3]) / gt[5])
            near = any(yy < 0 or xx < 0 or yy >= mh or xx >= mw or at(0, yy, xx) == -9999
                       for yy in range(y - 3, y + 4) for xx in range(x - 3, x + 4))
            if near and key != "disc edge":
                key += " (within 3 px of nodata)"
            d = [values[b] - truth[(row * tw + col) * nb + b] for b in range(nb)]
            if key == "ground":
                diffs[(row, col)] = d
            for k in (key, "all covered"):
                s = regions.setdefault(k, [[0.0] * nb, [0.0] * nb, 0])
                for b in range(nb):
                    s[0][b] += d[b] * d[b]
                    s[1][b] += d[b]
                s[2] += 1
    total = sum(regions["all covered"][0])
    for key, (sq, bias, n) in sorted(regions.items(), key=lambda kv: -kv[1][2]):
        print(f"{key:36s} {n:6d} px  PSNR {10 * math.log10(n * nb / sum(sq)):6.2f} dB  "
              f"{100 * sum(sq) / total:5.1f} % of the error  per band "
              + " ".join(f"{10 * math.log10(n / sq[b]):5.1f}" for b in range(nb))
              + "  bias " + " ".join(f"{bias[b] / n:+.4f}" for b in range(nb)))
    for f in (2, 4):
        sq, n = 0.0, 0
        for row in range(0, th - f + 1, f):
            for col in range(0, tw - f + 1, f):
                block = [diffs.get((row + dy, col + dx)) for dy in range(f) for dx in range(f)]
                if any(d is None for d in block):
                    continue
                for b in range(nb):
                    sq += (sum(d[b] for d in block) / (f * f)) ** 2
                    n += 1
        print(f"ground averaged over {f}x{f} px: PSNR {10 * math.log10(n / sq):.2f} dB "
              f"({n // nb} blocks)")


if __name__ == "__main__":
    main()
