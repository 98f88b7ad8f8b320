#!/usr/bin/env python3
"""Reads `ddhgs export` files with a PLY and .splat reader of its own (numpy
only, written from the formats' descriptions, sharing no code with ddhgs) and
checks them against the run's N-band gaussians.ply read the same way:

  - the exported PLY has exactly the standard 3DGS vertex layout (x y z nx ny
    nz f_dc_0..2 f_rest_0..44 opacity scale_0..2 rot_0..3, float32, binary
    little endian) that common viewers expect;
  - its geometry and opacities are the run's, row by row;
  - exported with --bands, its colour coefficients are the chosen bands' own;
  - the .splat file holds the same Gaussians (32-byte records, any order)
    with colours 0.5 + C0 f_dc and opacities sigmoid(opacity) in 8 bits.

Prints one JSON object; exit status 0 when every check passed.

usage: export_reader_check.py RUN_PLY EXPORT_PLY BAND_INDICES SPLAT
       (BAND_INDICES: the bands exported as R,G,B, e.g. 5,3,0)
"""
import json
import sys

import numpy as np

C0 = 0.28209479177387814
TYPES = {"float": "<f4", "float32": "<f4", "double": "<f8", "uchar": "u1", "uint8": "u1",
         "int": "<i4", "int32": "<i4", "uint": "<u4", "short": "<i2", "ushort": "<u2", "char": "i1"}


def read_ply(path):
    """(format, property names, structured array) of a PLY's vertex element."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    lines = data[:end].decode("ascii").splitlines()
    assert lines[0] == "ply", "not a PLY file"
    fmt, count, props, in_vertex = None, 0, [], False
    for line in lines[1:]:
        words = line.split()
        if words[0] == "format":
            fmt = words[1]
        elif words[0] == "element":
            in_vertex = words[1] == "vertex"
            if in_vertex:
                count = int(words[2])
            else:
                assert not props, "elements after vertex are not expected here"
        elif words[0] == "property" and in_vertex:
            assert words[1] != "list", "list properties are not expected in a Gaussian PLY"
            props.append((words[2], TYPES[words[1]]))
    assert fmt == "binary_little_endian", fmt
    dtype = np.dtype(props)
    rows = np.frombuffer(data, dtype=dtype, count=count, offset=end)
    assert end + count * dtype.itemsize == len(data), "file size disagrees with the header"
    return fmt, [p[0] for p in props], props, rows


def read_splat(path):
    record = np.dtype([("xyz", "<f4", 3), ("scale", "<f4", 3), ("rgba", "u1", 4), ("rot", "u1", 4)])
    data = np.fromfile(path, dtype=np.uint8)
    assert len(data) % record.itemsize == 0, "not a whole number of 32-byte records"
    return data.view(record)


def standard_layout():
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += ["f_rest_%d" % i for i in range(45)]
    return names + ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def run(run_ply, export_ply, band_text, splat):
    checks = {}
    _, _, _, source = read_ply(run_ply)
    fmt, names, props, out = read_ply(export_ply)
    checks["vertices"] = [int(len(source)), int(len(out))]
    checks["standard_layout"] = names == standard_layout() and all(t == "<f4" for _, t in props)
    geometry = ["x", "y", "z", "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    checks["geometry_equal"] = len(source) == len(out) and all(np.array_equal(source[g], out[g]) for g in geometry)

    bands = [int(b) for b in band_text.split(",")]
    source_rest = sum(1 for n in source.dtype.names if n.startswith("f_rest_")) // sum(
        1 for n in source.dtype.names if n.startswith("f_dc_"))
    colour_error = 0.0
    for j, b in enumerate(bands):
        colour_error = max(colour_error, float(np.abs(out["f_dc_%d" % j] - source["f_dc_%d" % b]).max()))
        for k in range(source_rest):
            got = out["f_rest_%d" % (j * 15 + k)]
            colour_error = max(colour_error, float(np.abs(got - source["f_rest_%d" % (b * source_rest + k)]).max()))
    checks["band_coefficient_error"] = colour_error

    records = read_splat(splat)
    checks["splat_records"] = int(len(records))
    order_ply = np.lexsort((out["z"], out["y"], out["x"]))
    order_splat = np.lexsort((records["xyz"][:, 2], records["xyz"][:, 1], records["xyz"][:, 0]))
    xyz = np.stack([out["x"], out["y"], out["z"]], 1)[order_ply]
    r = records[order_splat]
    checks["splat_positions_equal"] = len(r) == len(out) and bool(np.array_equal(r["xyz"], xyz))
    rgb = np.stack([out["f_dc_%d" % j] for j in range(3)], 1)[order_ply].astype(np.float64) * C0 + 0.5
    expected_rgb = np.round(np.clip(rgb, 0, 1) * 255)
    alpha = 1 / (1 + np.exp(-out["opacity"][order_ply].astype(np.float64)))
    scales = np.exp(np.stack([out["scale_%d" % a] for a in range(3)], 1)[order_ply].astype(np.float64))
    checks["splat_colour_max_step"] = float(np.abs(r["rgba"][:, :3] - expected_rgb).max())
    checks["splat_alpha_max_step"] = float(np.abs(r["rgba"][:, 3] - np.round(alpha * 255)).max())
    checks["splat_scale_rel_error"] = float(np.abs(r["scale"] / scales - 1).max())
    # Sorted largest (volume x opacity, from the PLY's values) first, as the
    # format's viewer streams them.
    row_of = {tuple(p): i for i, p in enumerate(np.stack([out["x"], out["y"], out["z"]], 1).tolist())}
    rows = [row_of[tuple(p)] for p in records["xyz"].tolist()]
    log_volume = sum(out["scale_%d" % a].astype(np.float64) for a in range(3))
    importance = (np.exp(log_volume) / (1 + np.exp(-out["opacity"].astype(np.float64))))[rows]
    checks["splat_sorted"] = bool(np.all(np.diff(importance) <= 1e-9 * importance.max()))

    checks["ok"] = bool(
        checks["standard_layout"] and checks["geometry_equal"] and colour_error < 1e-6
        and checks["splat_positions_equal"] and checks["splat_colour_max_step"] <= 1
        and checks["splat_alpha_max_step"] <= 1 and checks["splat_scale_rel_error"] < 1e-5
        and checks["splat_sorted"])
    return checks


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    try:
        checks = run(*sys.argv[1:])
    except Exception as e:  # reported as one line the C++ test shows
        checks = {"ok": False, "error": "%s: %s" % (type(e).__name__, e)}
    print(json.dumps(checks))
    sys.exit(0 if checks["ok"] else 1)


if __name__ == "__main__":
    main()
