#!/usr/bin/env python3
"""Independent reference for `nirslam entropy`: decodes PNGs with the standard library only (zlib,
no OpenCV) and computes the paper's Eq. 2-1 entropy H = -sum p_i log2 p_i over 256 bins.

Usage: entropy_reference.py IMAGE.png...   prints "path entropy_bits saturated black" per image.
Supports non-interlaced greyscale PNGs of 8 or 16 bits (16-bit binned by the top 8 bits)."""
import math
import struct
import sys
import zlib


def read_grey_png(path):
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind = data[pos + 4:pos + 8]
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    if colour != 0 or interlace != 0 or depth not in (8, 16):
        raise ValueError(f"{path}: only non-interlaced 8/16-bit greyscale PNGs are supported")
    bpp = depth // 8
    stride = width * bpp
    raw = zlib.decompress(idat)
    previous = bytearray(stride)
    values = []
    for y in range(height):
        filter_type = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            left = line[i - bpp] if i >= bpp else 0
            up = previous[i]
            up_left = previous[i - bpp] if i >= bpp else 0
            if filter_type == 1:
                line[i] = (line[i] + left) & 0xFF
            elif filter_type == 2:
                line[i] = (line[i] + up) & 0xFF
            elif filter_type == 3:
                line[i] = (line[i] + (left + up) // 2) & 0xFF
            elif filter_type == 4:
                p = left + up - up_left
                pa, pb, pc = abs(p - left), abs(p - up), abs(p - up_left)
                predictor = left if pa <= pb and pa <= pc else (up if pb <= pc else up_left)
                line[i] = (line[i] + predictor) & 0xFF
        previous = line
        if bpp == 1:
            values.extend(line)
        else:
            values.extend((line[i] << 8) | line[i + 1] for i in range(0, stride, 2))
    return values, depth


def main():
    for path in sys.argv[1:]:
        values, depth = read_grey_png(path)
        shift, top = depth - 8, (1 << depth) - 1
        counts = [0] * 256
        for v in values:
            counts[v >> shift] += 1
        n = len(values)
        entropy = -sum(c / n * math.log2(c / n) for c in counts if c)
        saturated = sum(1 for v in values if v == top) / n
        black = sum(1 for v in values if v == 0) / n
        print(f"{path} {entropy:.9f} {saturated:.9f} {black:.9f}")


if __name__ == "__main__":
    main()
