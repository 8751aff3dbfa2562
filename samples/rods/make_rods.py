#!/usr/bin/python3
"""Writes the rod samples (parafab rod requests, SI units): a helix, a tilted plane arc, the
three segments of the thesis's light sculpture (§5.9.5) under dead load, a curve whose
binormal lines no linear complex avoids (infeasible), and an S-curve with an inflection
(κ = 0: rejected with exit code 2). Run: /usr/bin/python3 samples/rods/make_rods.py"""
import json
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, note, points, **extra):
    req = {"name": name, "note": note,
           "curve": {"points": [[round(float(v), 9) for v in p] for p in points]}}
    req.update(extra)
    with open(os.path.join(HERE, name + ".json"), "w") as f:
        json.dump(req, f, indent=1)


t = np.linspace(0, 3 * math.pi, 91)
write("helix", "Circular helix r = 0.1 m, pitch 2*pi*0.03 m, 1.5 turns: a parallel curve (zero twist, "
      "constant sections). Ellipse elongated along the bending axis (t = 4 t*): stable.",
      np.c_[0.1 * np.cos(t), 0.1 * np.sin(t), 0.03 * t],
      max_radius=0.004, section={"factor": 4.0}, samples=400, validate=True)

t = np.linspace(0.2, 2.7, 81)
R = np.array([[1, 0, 0], [0, math.cos(0.5), -math.sin(0.5)], [0, math.sin(0.5), math.cos(0.5)]])
arc = np.c_[0.3 * np.cos(t), 0.15 * np.sin(t), np.zeros_like(t)] @ R.T
write("plane_arc", "Elliptic arc (0.3 m x 0.15 m) in a plane tilted by 0.5 rad: twist-free with "
      "the strip stiffness profile (Eq. 4.4), no loads.", arc, max_radius=0.005, samples=400, validate=True)


def sculpture(ta, tb, n=121, scale=0.2):
    u = np.linspace(ta, tb, n)
    return scale * np.c_[np.cos(u) + 0.25 * np.cos(u / 2 + 0.45), np.sin(u) + 0.25 * np.sin(u / 2 + 0.45),
                         0.4 * np.cos(1.5 * u)]


for k in range(3):
    write(f"sculpture_segment_{k}",
          f"Light sculpture (thesis §5.9.5) segment {k} at 0.2 m per unit, SmoothSil 960, largest mean "
          "radius 25 mm, designed under its own weight (dead-load fixed point, §5.8.2).",
          sculpture(k * 4 * math.pi / 3, (k + 1) * 4 * math.pi / 3),
          material={"preset": "SmoothSil 960"}, max_radius=0.025, samples=400,
          loads={"dead_load": True, "gravity": [0, 0, -9.81]}, validate=True)

A = [[-0.7, -0.0, -0.1, -0.0], [0.0, -0.1, 0.2, 0.1], [0.6, 0.2, 0.1, 0.0]]
B = [[-1.1, 0.1, -0.1, -0.1], [-0.3, 0.2, -0.1, 0.1], [-0.2, -0.2, -0.1, -0.0]]
u = np.linspace(0, 2 * math.pi * 0.9, 201)
four = np.zeros((len(u), 3))
for c in range(3):
    for k in range(1, 5):
        four[:, c] += A[c][k - 1] * np.cos(k * u) + B[c][k - 1] * np.sin(k * u)
write("infeasible_fourier", "A Fourier space curve whose binormal lines no linear complex avoids "
      "(Prop. 9): not an equilibrium curve of any Kirchhoff rod; the result names binding samples.",
      0.2 * four, samples=400)

x = np.linspace(-1, 1, 41)
write("invalid/kappa_zero", "A plane S-curve: kappa = 0 at its inflection (s = length/2); "
      "parafab rod exits 2 with the location.", 0.2 * np.c_[x, x**3 - x, np.zeros_like(x)])
