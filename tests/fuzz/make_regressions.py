#!/usr/bin/env python3
"""Writes tests/fuzz/regressions/: reader inputs (tests/fuzz/fuzz_target.h
encoding: one byte naming the reader, then the file) that once crashed a
reader, overflowed its size arithmetic or made it allocate what a corrupt
header claimed (issue 18). test_io replays them; add any input the fuzzer
finds (scripts/sanitize.sh leaves it in build-sanitize/fuzz-artifacts/).

    make_regressions.py [DIR]
"""
import math
import os
import struct
import sys
import zlib

# fuzz::ReaderKind
ENVI, TIFF, PNG, POINT_PLY, COLMAP_CAMERAS_BIN, COLMAP_POINTS_BIN = 2, 3, 4, 7, 8, 10


def envi(header, data):
    header = header.encode()
    return bytes([ENVI]) + struct.pack("<H", len(header)) + header + data


def tiff_claiming(width, height, strip_bytes, compression):
    """One page of 32-bit float samples in a single strip at offset 8."""
    entries = [(256, 4, width), (257, 4, height), (258, 3, 32), (259, 3, compression),
               (262, 3, 1), (273, 4, 8 + 2 + 9 * 12 + 4), (278, 4, height),
               (279, 4, strip_bytes), (339, 3, 3)]
    out = b"II*\0" + struct.pack("<I", 8) + struct.pack("<H", len(entries))
    for tag, kind, value in entries:
        out += struct.pack("<HHII", tag, kind, 1, value)
    return bytes([TIFF]) + out + struct.pack("<I", 0) + bytes(strip_bytes)


def png_claiming(width, height):
    """A valid 4 x 6 RGB PNG whose IHDR then claims width x height."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(
            ">I", zlib.crc32(kind + body))
    rows = b"".join(b"\0" + bytes(4 * 3) for _ in range(6))
    png = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
           + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))
    return bytes([PNG]) + png


def colmap_point(x, y, z):
    point = struct.pack("<Q", 1) + struct.pack("<Qddd", 1, x, y, z) + bytes(3)
    return bytes([COLMAP_POINTS_BIN]) + point + struct.pack("<dQ", 0.5, 0)


def colmap_camera(width, height):
    camera = struct.pack("<QiiQQ", 1, 1, 1, width, height) + struct.pack("<4d", 5, 5, 4, 3)
    return bytes([COLMAP_CAMERAS_BIN]) + camera


CASES = {
    # 2^22 cubed samples: the byte count wrapped to a small number.
    "envi_size_overflow": envi("ENVI\nsamples = 4194304\nlines = 4194304\nbands = 4194304\n"
                               "data type = 2\ninterleave = bsq\n", bytes(64)),
    # 14 GB of samples announced by a 200-byte file, raw and deflated.
    "tiff_huge_raw": tiff_claiming(60000, 60000, 48, 1),
    "tiff_huge_deflate": tiff_claiming(60000, 60000, 48, 8),
    # 768 MB of pixels from a tiny PNG.
    "png_huge": png_claiming(16000, 16000),
    # A list whose count is a double: read as a huge or negative count.
    "ply_float_list_count": bytes([POINT_PLY]) + (
        b"ply\nformat binary_little_endian 1.0\nelement face 1\nproperty list double int index\n"
        b"element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
        + b"\xff" * 64),
    # NaN points reached training as "index out of range in self".
    "colmap_point_nan": colmap_point(1.0, math.nan, 0.0),
    # A camera 2^40 pixels wide.
    "colmap_camera_huge": colmap_camera(1 << 40, 6),
}


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__),
                                                             "regressions")
    os.makedirs(out, exist_ok=True)
    for name, data in CASES.items():
        with open(os.path.join(out, name), "wb") as f:
            f.write(data)


if __name__ == "__main__":
    main()
