#!/usr/bin/env python3
"""PSNR (dB, RGB, values in [0, 1]) between 8-bit PNG images, without numpy or PIL.

Usage: png_psnr.py REFERENCE IMAGE [IMAGE ...]   prints one line per IMAGE: "<psnr> <path>".
Reads non-interlaced 8-bit RGB or RGBA PNGs (what `atex render` writes); alpha is ignored.
"""
import struct
import sys
import zlib


def read_png(path):
    data = open(path, 'rb').read()
    if data[:8] != b'\x89PNG\r\n\x1a\n':
        raise SystemExit(f'{path}: not a PNG')
    pos, idat, width, height, ctype = 8, b'', 0, 0, 0
    while pos < len(data):
        length, kind = struct.unpack('>I4s', data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b'IHDR':
            width, height, depth, ctype, _, _, interlace = struct.unpack('>IIBBBBB', body)
            if depth != 8 or ctype not in (2, 6) or interlace:
                raise SystemExit(f'{path}: only 8-bit RGB/RGBA non-interlaced PNGs are read')
        elif kind == b'IDAT':
            idat += body
        pos += 12 + length
    channels = 3 if ctype == 2 else 4
    raw = zlib.decompress(idat)
    stride = width * channels
    rows, prev = [], bytearray(stride)
    for y in range(height):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(line)
        prev = line
    pixels = [row[x * channels + k] for row in rows for x in range(width) for k in range(3)]
    return width, height, pixels


def psnr(a, b):
    if a[:2] != b[:2]:
        raise SystemExit('image sizes differ')
    se = sum((p - q) ** 2 for p, q in zip(a[2], b[2]))
    mse = se / len(a[2]) / 255.0 ** 2
    return float('inf') if mse == 0 else -10 * __import__('math').log10(mse)


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    ref = read_png(sys.argv[1])
    for path in sys.argv[2:]:
        print(f'{psnr(ref, read_png(path)):.3f} {path}')


if __name__ == '__main__':
    main()
