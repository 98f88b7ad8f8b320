#!/usr/bin/env python3
"""Feeds ddhgs malformed inputs, one at a time, and lists the error lines that
name neither the file nor the flag at fault, or that carry a library's raw text
(issue 18). Every case damages a copy inside WORK; nothing else is touched.

    probe_errors.py DDHGS_BINARY WORK      exit 1 when any case fails the rule

A case passes when ddhgs exits 1 with exactly one "error: " line that names
the damaged file (or the flag, or the config key) and holds none of the raw
texts of LibTorch, nlohmann-json or the C++ runtime; a crash, an exit 0 or a
stack trace fails it.
"""
import json
import os
import shutil
import struct
import subprocess
import sys

RAW_TEXTS = ["json.exception", "bad_alloc", "c10::", "enforce fail", "frame #", "terminate called",
             "index out of range in self", "Expected ", "basic_string", "std::", "what():",
             "Segmentation", "stoi", "stod"]


def run(binary, args):
    proc = subprocess.run([binary] + args, capture_output=True, text=True, timeout=600)
    return proc.returncode, proc.stdout + proc.stderr


class Probe:
    def __init__(self, binary, work):
        self.binary, self.work = binary, work
        self.failures, self.cases = [], 0
        self.scene = self.fresh("base_scene_src")
        self.must(["-q", "synth", "--preset", "demo", "--width", "32", "--height", "24",
                   "--bands", "4", "--views", "12", "--out", self.scene])
        self.run_dir = os.path.join(work, "base_run")
        self.must(["-q", "train", self.scene, "--out", self.run_dir, "--preset", "demo",
                   "--iterations", "20", "--checkpoint-every", "10"])
        self.camera = os.path.join(work, "camera.json")
        with open(self.camera, "w") as f:
            json.dump({"width": 32, "height": 24, "fx": 40, "fy": 40, "cx": 16, "cy": 12,
                       "world_to_camera": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4],
                                           [0, 0, 0, 1]]}, f)

    def fresh(self, name):
        path = os.path.join(self.work, name)
        shutil.rmtree(path, ignore_errors=True)
        return path

    def must(self, args):
        rc, out = run(self.binary, args)
        if rc != 0:
            raise SystemExit("probe set-up failed: ddhgs %s\n%s" % (" ".join(args), out))

    def copy_scene(self, name):
        dst = self.fresh(name)
        shutil.copytree(self.scene, dst)
        return dst

    def copy_run(self, name):
        dst = self.fresh(name)
        shutil.copytree(self.run_dir, dst)
        os.remove(os.path.join(dst, ".ddhgs-lock"))
        return dst

    def check(self, name, args, named):
        """Runs ddhgs ARGS; the error must name one of `named`."""
        self.cases += 1
        rc, out = run(self.binary, args)
        errors = [line.strip() for line in out.splitlines() if line.startswith("error: ")]
        expected_rc = 1
        if not errors and (args[1:2] == ["info"] or args[:1] == ["info"]):
            # `info` may list every problem it finds, indented, describing the scene.
            errors = [line.strip() for line in out.splitlines() if line.startswith("  error: ")]
            expected_rc = rc if rc in (0, 1) else 1
        problem = None
        if rc != expected_rc:
            problem = "exit %d" % rc
        elif len(errors) != 1:
            problem = "%d error lines" % len(errors)
        elif not any(n in errors[0] for n in named):
            problem = "names none of %s" % named
        elif any(raw in out for raw in RAW_TEXTS):
            problem = "raw library text"
        if problem:
            shown = errors[0] if errors else out.strip().splitlines()[-1:] or ["(no output)"]
            self.failures.append("%s: %s: %s" % (name, problem, shown))


def write(path, data, mode="w"):
    with open(path, mode) as f:
        f.write(data)


def npy_bytes(shape, descr="<f4", payload=b""):
    header = "{'descr': '%s', 'fortran_order': False, 'shape': %s, }" % (descr, shape)
    header += " " * ((64 - (10 + len(header) + 1) % 64) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(header)) + header.encode() + payload


def cube_cases(p):
    variants = {
        "truncated": lambda path: write(path, open(path, "rb").read()[:200], "wb"),
        "garbage": lambda path: write(path, b"\x00garbage" * 20, "wb"),
        "empty": lambda path: write(path, b"", "wb"),
        "huge_shape": lambda path: write(path, npy_bytes("(100000, 100000, 40)", "<u2"), "wb"),
        "bands_mismatch": lambda path: write(path, npy_bytes("(24, 32, 5)", "<u2", b"\0" * 7680), "wb"),
        "size_mismatch": lambda path: write(path, npy_bytes("(20, 32, 4)", "<u2", b"\0" * 5120), "wb"),
        "complex": lambda path: write(path, npy_bytes("(24, 32, 4)", "<c8", b"\0" * 24576), "wb"),
        "one_dim": lambda path: write(path, npy_bytes("(3072,)", "<u2", b"\0" * 6144), "wb"),
        "nan": lambda path: write(path, npy_bytes("(24, 32, 4)", "<f4",
                                                  struct.pack("<f", float("nan")) * 3072), "wb"),
        "huge_values": lambda path: write(path, npy_bytes("(24, 32, 4)", "<f4",
                                                          struct.pack("<f", 3e38) * 3072), "wb"),
    }
    for name, damage in variants.items():
        for view in ["r_003", "r_010"]:  # a training view, the held-out view
            scene = p.copy_scene("cube_%s_%s" % (name, view))
            path = os.path.join(scene, "hyperspectral", view + ".npy")
            damage(path)
            for command in (["info", scene], ["train", scene, "--out", scene + "_run", "--preset",
                                              "demo", "--iterations", "20"]):
                if command[0] == "info" and name in ("nan", "huge_values"):
                    continue  # info reads only a few cubes in full
                p.check("cube %s %s %s" % (name, view, command[0]), ["-q"] + command, [path])


def transforms_cases(p):
    base = json.load(open(os.path.join(p.scene, "transforms.json")))

    def edit(name, change, named=None):
        scene = p.copy_scene("transforms_" + name)
        path = os.path.join(scene, "transforms.json")
        doc = json.loads(json.dumps(base))
        text = change(doc)
        write(path, text if isinstance(text, str) else json.dumps(doc))
        p.check("transforms " + name, ["-q", "info", scene], named or [path])
        p.check("transforms %s train" % name,
                ["-q", "train", scene, "--out", scene + "_run", "--preset", "demo",
                 "--iterations", "20"], named or [path])

    edit("invalid_json", lambda d: '{"frames": [')
    edit("not_object", lambda d: "[1, 2]")
    edit("frames_not_list", lambda d: d.update(frames=7))
    edit("no_frames", lambda d: d.update(frames=[]))
    edit("matrix_strings", lambda d: d["frames"][0].update(transform_matrix="eye"))
    edit("matrix_rows", lambda d: d["frames"][0].update(transform_matrix=[[1, 0, 0, 0]]))
    edit("width_zero", lambda d: d.update(w=0))
    edit("focal_negative", lambda d: d.update(fl_x=-3))
    edit("focal_string", lambda d: d.update(fl_x="big"))
    edit("wavelength_count", lambda d: d.update(wavelengths=[500, 600]))
    edit("wavelength_string", lambda d: d.update(wavelengths=["red"] * 4))
    edit("wavelength_negative", lambda d: d["wavelengths"].__setitem__(0, -1.0))
    edit("all_missing", lambda d: [f.update(hyperspectral_file_path="nope/" + str(i) + ".npy")
                                   for i, f in enumerate(d["frames"])])
    edit("train_unknown", lambda d: d.update(train_filenames=["nope.npy"]))
    edit("split_both", lambda d: d.update(train_filenames=[d["frames"][0]["hyperspectral_file_path"]],
                                          test_filenames=[d["frames"][0]["hyperspectral_file_path"]]))
    edit("scale_zero", lambda d: d.update(scale=0))
    edit("camera_model", lambda d: d.update(camera_model="FISHEYE"))
    edit("duplicate", lambda d: d["frames"].__setitem__(3, d["frames"][1]))

    scene = p.copy_scene("points_garbage")
    write(os.path.join(scene, "points.ply"), "ply\nformat ascii 1.0\nelement vertex 5\nend_header\n")
    p.check("points.ply no properties", ["-q", "train", scene, "--out", scene + "_run", "--preset",
                                         "demo", "--iterations", "20"],
            [os.path.join(scene, "points.ply")])
    scene = p.copy_scene("points_truncated")
    path = os.path.join(scene, "points.ply")
    write(path, open(path, "rb").read()[:300], "wb")
    p.check("points.ply truncated", ["-q", "info", scene], [path])


def colmap_cases(p):
    def model(name, files):
        scene = p.fresh("colmap_" + name)
        os.makedirs(os.path.join(scene, "sparse", "0"))
        shutil.copytree(os.path.join(p.scene, "hyperspectral"), os.path.join(scene, "hyperspectral"))
        for file, data in files.items():
            write(os.path.join(scene, "sparse", "0", file), data, "wb" if isinstance(data, bytes) else "w")
        return scene

    cams = "1 PINHOLE 32 24 40 40 16 12\n"
    images = "".join("%d 1 0 0 0 0 0 4 1 r_%03d.png\n\n" % (i + 1, i) for i in range(12))
    cases = {
        "cameras_bad_number": ({"cameras.txt": "1 PINHOLE 32 24 forty 40 16 12\n",
                                "images.txt": images}, "cameras.txt"),
        "cameras_unknown_model": ({"cameras.txt": "1 FISHEYE_X 32 24 40 40 16 12\n",
                                   "images.txt": images}, "cameras.txt"),
        "images_missing_camera": ({"cameras.txt": cams, "images.txt": images.replace(" 1 r_", " 9 r_")},
                                  "images.txt"),
        "images_zero_quaternion": ({"cameras.txt": cams, "images.txt": images.replace(" 1 0 0 0 ", " 0 0 0 0 ")},
                                   "images.txt"),
        "cameras_bin_truncated": ({"cameras.bin": b"\x05" + b"\0" * 10, "images.bin": b"\0" * 8},
                                  "cameras.bin"),
        "points_bin_nan": ({"cameras.txt": cams, "images.txt": images,
                            "points3D.txt": "1 nan 0 0 1 2 3 0.5\n"}, "points3D.txt"),
    }
    point = struct.pack("<Q", 1) + struct.pack("<Q3d3Bd", 7, float("nan"), 0, 0, 1, 2, 3, 0.5) \
        + struct.pack("<Q", 0)
    cam_bin = struct.pack("<QiiQQ4d", 1, 1, 1, 32, 24, 40, 40, 16, 12)
    img_bin = struct.pack("<Q", 12) + b"".join(
        struct.pack("<i4d3di", i + 1, 1, 0, 0, 0, 0, 0, 4, 1) + b"r_%03d.png\0" % i + struct.pack("<Q", 0)
        for i in range(12))
    cases["points_bin_nan_binary"] = ({"cameras.bin": cam_bin, "images.bin": img_bin,
                                       "points3D.bin": point}, "points3D.bin")
    for name, (files, bad) in cases.items():
        scene = model(name, files)
        named = [os.path.join(scene, "sparse", "0", bad), os.path.join(scene, "sparse", "0")]
        p.check("colmap " + name, ["-q", "train", scene, "--out", scene + "_run", "--preset", "demo",
                                   "--iterations", "20"], named)


def run_cases(p):
    def damaged(name, file, data):
        run = p.copy_run("run_" + name)
        path = os.path.join(run, file)
        if data is None:
            os.remove(path)
        else:
            write(path, data, "wb" if isinstance(data, bytes) else "w")
        return run, path

    def truncate(path_in_run):
        return open(os.path.join(p.run_dir, path_in_run), "rb").read()[:100]

    commands = {
        "eval": lambda run: ["eval", run],
        "render": lambda run: ["render", run],
        "export": lambda run: ["export", run],
        "report": lambda run: ["report", run],
        "resume": lambda run: ["train", "--resume", run, "--iterations", "30"],
    }
    files = {
        "config_invalid": ("config.json", "{not json"),
        "config_array": ("config.json", "[]"),
        "config_old_version": ("config.json", json.dumps({"format_version": 1})),
        "config_missing_key": ("config.json", json.dumps({"format_version": 2})),
        "config_wrong_type": ("config.json", open(os.path.join(p.run_dir, "config.json")).read()
                              .replace('"iterations": 20', '"iterations": "twenty"')),
        "config_bad_value": ("config.json", open(os.path.join(p.run_dir, "config.json")).read()
                             .replace('"sh_degree": 3', '"sh_degree": 9')),
        "ply_truncated": ("gaussians.ply", truncate("gaussians.ply")),
        "ply_garbage": ("gaussians.ply", b"\x00" * 500),
        "ply_missing": ("gaussians.ply", None),
        "checkpoint_truncated": ("checkpoint.pt", truncate("checkpoint.pt")),
        "checkpoint_garbage": ("checkpoint.pt", b"PK\x03\x04" + b"\x00" * 200),
        "background_garbage": ("background.json", "{]"),
        "metrics_garbage": ("metrics.jsonl", "not json\n{}\n"),
        "summary_garbage": ("train_summary.json", "[[["),
    }
    for name, (file, data) in files.items():
        for cname, command in commands.items():
            if cname == "resume" and file in ("gaussians.ply",):
                continue
            if name.startswith("metrics") and cname != "report":
                continue
            if name.startswith("summary") and cname not in ("report",):
                continue
            if name.startswith("checkpoint") and cname != "resume":
                continue
            if name.startswith("background") and cname == "resume":
                continue  # a resumed run takes its background from the checkpoint
            run, path = damaged("%s_%s" % (name, cname), file, data)
            named = [path, os.path.join(run, "config.json")] if file == "config.json" else [path]
            p.check("run %s %s" % (name, cname), ["-q"] + command(run), named)


def flag_cases(p):
    out = os.path.join(p.work, "flag_out")
    train = ["-q", "train", p.scene, "--out", out]
    for name, extra, named in [
        ("preset", ["--preset", "nope"], ["nope"]),
        ("set_syntax", ["--set", "iterations"], ["--set"]),
        ("iterations", ["--iterations", "-3"], ["--iterations"]),
        ("set_unknown", ["--set", "optim.nope=1"], ["optim.nope"]),
        ("set_type", ["--set", "iterations=many"], ["iterations"]),
        ("band_range", ["--band-range", "a:b"], ["--band-range"]),
        ("band_range_empty", ["--band-range", "2000:3000"], ["2000", "band"]),
        ("downscale", ["--downscale", "0"], ["downscale"]),
        ("bin", ["--bin", "0"], ["bin"]),
        ("bin_too_big", ["--bin", "9"], ["--bin"]),
        ("background_count", ["--set", "model.background=[0.1,0.2]"], ["model.background"]),
    ]:
        p.check("train flag " + name, train + extra, named)
    ply = os.path.join(p.run_dir, "gaussians.ply")
    p.check("render-ply camera garbage", ["-q", "render-ply", ply, "--camera", ply, "--out",
                                          os.path.join(p.work, "x.npy")], [ply])
    p.check("render-ply background", ["-q", "render-ply", ply, "--camera", p.camera, "--out",
                                      os.path.join(p.work, "x.npy"), "--background", "1,2"],
            ["--background"])
    p.check("synth width", ["-q", "synth", "--width", "3", "--out", os.path.join(p.work, "s")],
            ["--width"])
    p.check("synth huge", ["-q", "synth", "--width", "2000000", "--height", "2000000", "--out",
                           os.path.join(p.work, "s")], ["--width"])


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    binary, work = sys.argv[1], os.path.abspath(sys.argv[2])
    os.makedirs(work, exist_ok=True)
    p = Probe(binary, work)
    only = os.environ.get("PROBE_ONLY", "")
    for group in (cube_cases, transforms_cases, colmap_cases, run_cases, flag_cases):
        if not only or only in group.__name__:
            group(p)
    for failure in p.failures:
        print(failure)
    print("%d cases, %d error lines fail the rule" % (p.cases, len(p.failures)))
    return 1 if p.failures else 0


if __name__ == "__main__":
    sys.exit(main())
