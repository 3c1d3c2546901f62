#!/usr/bin/python3
"""Make docs/gallery/flame-pot.png: the campfire without the pot
(docs/gallery/flame-puffing.toml, frame 130) beside frames of the campfire under the
pot (docs/gallery/flame-pot.toml), with the pot drawn over them. The flame renderer
draws only the flame; this draws the pot's silhouette where the scene's camera sees
the obstacle (radius 0.25 m, from 0.42 to 0.5 m over the burner): a dark iron side
and the rim's ellipse, projected by the scene's pinhole camera (at (0, 0.7, 2.6) m
looking along -z, 40 degrees of vertical field, 1280 x 720).

  phenomena render docs/gallery/flame-puffing.toml --out /tmp/puf --frames 130..131
  phenomena render docs/gallery/flame-pot.toml --out /tmp/pot --frames 118..144
  tools/gallery/pot_overlay.py /tmp/puf /tmp/pot docs/gallery/flame-pot.png
"""

import math
import sys

from PIL import Image, ImageDraw

W, H, FOV_Y = 1280, 720, 40.0
EYE = (0.0, 0.7, 2.6)
F = (H / 2) / math.tan(math.radians(FOV_Y / 2))
RADIUS, BOTTOM, TOP = 0.25, 0.42, 0.5
CROP = (440, 140, 840, 720)


def project(x, y, z):
    depth = EYE[2] - z
    return (W / 2 + F * (x - EYE[0]) / depth, H / 2 - F * (y - EYE[1]) / depth)


def rim(y, steps=64):
    return [project(RADIUS * math.cos(a), y, RADIUS * math.sin(a)) for a in (2 * math.pi * k / steps for k in range(steps))]


def draw_pot(image):
    d = ImageDraw.Draw(image)
    bottom, top = rim(BOTTOM), rim(TOP)
    # The side: the front half of the bottom rim and the top rim's outline.
    front = [p for p, a in zip(bottom, range(64)) if a <= 32]
    side = [project(RADIUS, TOP, 0.0)] + front + [project(-RADIUS, TOP, 0.0)]
    d.polygon(side, fill=(22, 20, 19))
    d.polygon(top, fill=(34, 31, 29), outline=(60, 55, 50))
    return image


def main(no_pot_dir, pot_dir, out):
    panels = [Image.open(f"{no_pot_dir}/frame_00130.png").convert("RGB").crop(CROP)]
    for frame in (124, 130, 136, 142):
        panels.append(draw_pot(Image.open(f"{pot_dir}/frame_{frame:05d}.png").convert("RGB")).crop(CROP))
    w, h = panels[0].size
    sheet = Image.new("RGB", (w * len(panels), h))
    for k, p in enumerate(panels):
        sheet.paste(p, (k * w, 0))
    sheet.save(out, optimize=True)


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
