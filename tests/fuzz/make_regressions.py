#!/usr/bin/env python3
"""Writes tests/fuzz/regressions/: reader inputs (tests/fuzz/fuzz_target.h
encoding: one byte naming the reader, then the file) that once crashed a
reader, overflowed its size arithmetic or made it allocate what a corrupt
header claimed. test_io replays them; add any input the fuzzer
finds (scripts/sanitize.sh leaves it in build-sanitize/fuzz-artifacts/).

    make_regressions.py [DIR]
"""
import io
import math
import os
import struct
import sys
import zipfile
import zlib

# fuzz::ReaderKind
TORCH_PT, ENVI, TIFF, PNG, JPEG, POINT_PLY, COLMAP_CAMERAS_BIN, COLMAP_POINTS_BIN = 1, 2, 3, 4, 5, 7, 8, 10


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


def torch_pt(pickle):
    """A torch.save archive (stored zip entries, as torch.save writes them)."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_STORED) as archive:
        for name, data in (("data.pkl", pickle), ("version", b"3\n")):
            archive.writestr(zipfile.ZipInfo("archive/" + name, (1980, 1, 1, 0, 0, 0)), data)
    return bytes([TORCH_PT]) + out.getvalue()


def torch_pt_declaring(name, method, size):
    """torch_pt of a valid pickle whose central directory then says record
    `name` is compressed with `method` and `size` bytes long."""
    pt = bytearray(torch_pt(b"\x80\x02N."))
    entry = pt.find(b"PK\x01\x02")
    while not pt[entry + 46:].startswith(b"archive/" + name):
        entry = pt.find(b"PK\x01\x02", entry + 4)
    struct.pack_into("<H", pt, entry + 10, method)
    struct.pack_into("<I", pt, entry + 24, size)
    return bytes(pt)


def jpeg_segment(marker, body):
    return bytes([0xFF, marker]) + struct.pack(">H", len(body) + 2) + body


# A Huffman table of 320 codes: stb_image (v2.27) writes past a 257-entry
# array while building it, wherever in the file stb meets it.
TOO_MANY_CODES = bytes([0x10]) + bytes([20] * 16) + bytes(320)


def jpeg_scan_then(tail):
    """A decodable 8 x 8 grey baseline JPEG whose scan is followed by tail."""
    dc_table = bytes([0x00, 1]) + bytes(15) + bytes([0])  # one 1-bit code: category 0
    ac_table = bytes([0x10, 1]) + bytes(15) + bytes([0])  # one 1-bit code: end of block
    return (b"\xFF\xD8" + jpeg_segment(0xDB, bytes(1) + bytes([1] * 64))
            + jpeg_segment(0xC0, struct.pack(">BHHB", 8, 8, 8, 1) + bytes([1, 0x11, 0]))
            + jpeg_segment(0xC4, dc_table + ac_table)
            + jpeg_segment(0xDA, bytes([1, 1, 0, 0, 63, 0]))
            + bytes([0x3F]) + tail)  # DC 0, end of block, padding ones


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
    # Huffman tables stb meets where the first check (walking marker segments
    # by their length up to the first scan) did not look: after fill bytes
    # before the start of image, after junk bytes between segments (the
    # fuzzer's second find, stb_jpeg_huffman_after_padding), read past the
    # end its segment declares, and after the first scan.
    "jpeg_huffman_after_fill_bytes": bytes([JPEG]) + b"\xFF\xFF\xD8"
    + jpeg_segment(0xC4, TOO_MANY_CODES),
    "jpeg_huffman_after_junk": bytes([JPEG]) + b"\xFF\xD8" + jpeg_segment(0xFE, b"ddhgs")
    + b"junk" + jpeg_segment(0xC4, TOO_MANY_CODES),
    "jpeg_huffman_past_its_segment": bytes([JPEG]) + b"\xFF\xD8\xFF\xC4\x00\x03"
    + TOO_MANY_CODES,
    "jpeg_huffman_after_scan": bytes([JPEG])
    + jpeg_scan_then(jpeg_segment(0xC4, TOO_MANY_CODES) + b"\xFF\xD9"),
    # LibTorch 1.13's unpickler pops an empty stack (BINPERSID first): a
    # segfault. (The fuzzer's torch_pt_huge_string declares a 4 GB string.)
    "torch_pt_empty_stack": torch_pt(b"\x80\x02Q."),
    # LibTorch allocates the size a zip entry declares, then reads the
    # uninitialised memory as the record: 4 GB "deflated" in 200 bytes.
    "torch_pt_huge_record": torch_pt_declaring(b"data.pkl", 8, 0xF0000000),
    # The same for the version record, which LibTorch extracts while it
    # opens the archive (the fuzzer found it: malloc of 4 GB).
    "torch_pt_huge_version_record": torch_pt_declaring(b"version", 8, 0xFFFFFFFF),
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
