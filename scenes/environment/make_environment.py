#!/usr/bin/env python3
"""Writes the bundled example environment map for lens flare (scenes/environment/sky_env.exr).

A lat-long (equirectangular) RGB map, 128 x 64 half float, uncompressed
single-part OpenEXR (written by hand: no OpenEXR module needed). Texel (i, j)
looks along longitude 360 (i + 0.5) / 128 - 180 degrees (0 = straight ahead
of a camera with flare.environment_yaw_deg = 0, + to the right) and latitude
90 - 180 (j + 0.5) / 64 degrees (row 0 = the zenith): see
core/lens/flare_environment.h. Radiance in the bundled scenes' units:

- a sky from 1.5 (zenith) to 3 (horizon), a ground of 0.3 below the horizon;
- a sun of radiance 2000 (one texel) at longitude +1.4, latitude +26.7:
  just above the top edge of the bundled 640 x 480 scenes' 28 mm view
  (half field 32.7 x 25.7 degrees; it projects to about (332, -11)), so its
  glare reaches the top rows and its ghosts fall in the frame;
- a street lamp of radiance 300 behind the camera (longitude 180): haze only.

Usage: python3 make_environment.py OUT.exr
"""
import math
import struct
import sys

W, H = 128, 64


def radiance(i, j):
    lon = 360.0 * (i + 0.5) / W - 180.0
    lat = 90.0 - 180.0 * (j + 0.5) / H
    if lat >= 0:
        t = lat / 90.0
        rgb = [1.2 + 1.0 * (1 - t), 1.6 + 1.0 * (1 - t), 2.4 + 0.6 * (1 - t)]
    else:
        rgb = [0.3, 0.28, 0.25]
    if i == 64 and j == 22:  # the sun (lon 1.4, lat 26.7)
        rgb = [2000.0, 1900.0, 1700.0]
    if i == 127 and j == 33:  # the lamp behind the camera (lon 178.6, lat -4.2)
        rgb = [300.0, 260.0, 180.0]
    return rgb


def attribute(name, kind, data):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def main(path):
    box = struct.pack("<iiii", 0, 0, W - 1, H - 1)
    channels = b"".join(c.encode() + b"\0" + struct.pack("<iBBBBii", 1, 0, 0, 0, 0, 1, 1) for c in "BGR") + b"\0"
    header = b"".join([
        attribute("channels", "chlist", channels),
        attribute("compression", "compression", b"\0"),  # none
        attribute("dataWindow", "box2i", box),
        attribute("displayWindow", "box2i", box),
        attribute("lineOrder", "lineOrder", b"\0"),  # increasing y
        attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)),
        attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0)),
        attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)),
    ]) + b"\0"
    start = 8 + len(header) + 8 * H
    line_bytes = 3 * W * 2
    chunk = 8 + line_bytes
    out = bytearray(struct.pack("<ii", 20000630, 2)) + header
    out += b"".join(struct.pack("<Q", start + y * chunk) for y in range(H))
    for y in range(H):
        row = [radiance(i, y) for i in range(W)]
        out += struct.pack("<ii", y, line_bytes)
        for c in (2, 1, 0):  # channels in name order: B, G, R
            out += b"".join(struct.pack("<e", px[c]) for px in row)
    with open(path, "wb") as f:
        f.write(out)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "sky_env.exr")
