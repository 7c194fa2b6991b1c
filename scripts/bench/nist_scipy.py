#!/usr/bin/env python3
"""scipy's MINPACK LM (least_squares(method='lm')) on the 27 NIST StRD problems, both starts:
the certified digits it reaches, for the side-by-side with
`cargo run --release -p visuotact-nn --example nist`.

Usage: PEER_WORK=/tmp/visuotact-peers $PEER_WORK/venv/bin/python scripts/bench/nist_scipy.py [DIR]
"""
import glob
import math
import os
import re
import sys

import numpy as np
from scipy.optimize import least_squares

PI = math.pi
M = {
    "Misra1a": lambda b, x: b[0] * (1 - np.exp(-b[1] * x)),
    "BoxBOD": lambda b, x: b[0] * (1 - np.exp(-b[1] * x)),
    "Chwirut1": lambda b, x: np.exp(-b[0] * x) / (b[1] + b[2] * x),
    "Chwirut2": lambda b, x: np.exp(-b[0] * x) / (b[1] + b[2] * x),
    "Lanczos1": lambda b, x: b[0] * np.exp(-b[1] * x) + b[2] * np.exp(-b[3] * x) + b[4] * np.exp(-b[5] * x),
    "Gauss1": lambda b, x: b[0] * np.exp(-b[1] * x) + b[2] * np.exp(-((x - b[3]) / b[4]) ** 2) + b[5] * np.exp(-((x - b[6]) / b[7]) ** 2),
    "DanWood": lambda b, x: b[0] * x ** b[1],
    "Misra1b": lambda b, x: b[0] * (1 - (1 + b[1] * x / 2) ** -2),
    "Kirby2": lambda b, x: (b[0] + b[1] * x + b[2] * x ** 2) / (1 + b[3] * x + b[4] * x ** 2),
    "Hahn1": lambda b, x: (b[0] + b[1] * x + b[2] * x ** 2 + b[3] * x ** 3) / (1 + b[4] * x + b[5] * x ** 2 + b[6] * x ** 3),
    "MGH17": lambda b, x: b[0] + b[1] * np.exp(-x * b[3]) + b[2] * np.exp(-x * b[4]),
    "Misra1c": lambda b, x: b[0] * (1 - (1 + 2 * b[1] * x) ** -0.5),
    "Misra1d": lambda b, x: b[0] * b[1] * x / (1 + b[1] * x),
    "Roszman1": lambda b, x: b[0] - b[1] * x - np.arctan(b[2] / (x - b[3])) / PI,
    "ENSO": lambda b, x: b[0] + b[1] * np.cos(2 * PI * x / 12) + b[2] * np.sin(2 * PI * x / 12) + b[4] * np.cos(2 * PI * x / b[3]) + b[5] * np.sin(2 * PI * x / b[3]) + b[7] * np.cos(2 * PI * x / b[6]) + b[8] * np.sin(2 * PI * x / b[6]),
    "MGH09": lambda b, x: b[0] * (x ** 2 + x * b[1]) / (x ** 2 + x * b[2] + b[3]),
    "Rat42": lambda b, x: b[0] / (1 + np.exp(b[1] - b[2] * x)),
    "MGH10": lambda b, x: b[0] * np.exp(b[1] / (x + b[2])),
    "Eckerle4": lambda b, x: (b[0] / b[1]) * np.exp(-0.5 * ((x - b[2]) / b[1]) ** 2),
    "Rat43": lambda b, x: b[0] / ((1 + np.exp(b[1] - b[2] * x)) ** (1 / b[3])),
    "Bennett5": lambda b, x: b[0] * (b[1] + x) ** (-1 / b[2]),
}
for a, b in [("Lanczos2", "Lanczos1"), ("Lanczos3", "Lanczos1"), ("Gauss2", "Gauss1"), ("Gauss3", "Gauss1"), ("Thurber", "Hahn1")]:
    M[a] = M[b]


def parse(path):
    lines = open(path).read().splitlines()
    text = "\n".join(lines)
    s0, s1 = map(int, re.search(r"Starting Values\s+\(lines\s+(\d+)\s+to\s+(\d+)\)", text).groups())
    d0, d1 = map(int, re.search(r"Data\s+\(lines\s+(\d+)\s+to\s+(\d+)\)", text).groups())
    st1, st2, cert = [], [], []
    for l in lines[s0 - 1:s1]:
        v = [float(t) for t in l.split("=")[1].split()]
        st1.append(v[0]); st2.append(v[1]); cert.append(v[2])
    rss = float([l for l in lines if "Residual Sum of Squares" in l][0].split()[-1])
    data = np.array([[float(t) for t in l.split()] for l in lines[d0 - 1:d1]])
    return st1, st2, cert, rss, data


def lre(e, c):
    if not np.isfinite(e):
        return 0.0
    r = abs(e - c) / abs(c) if c != 0 else abs(e)
    return 11.0 if r == 0 else min(11.0, max(0.0, -math.log10(r)))


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "../../testdata/reference/nist_strd")
    four = total = 0
    print(f"{'problem':<10} {'start':>5} {'params':>8} {'rss':>8}")
    for p in sorted(glob.glob(os.path.join(d, "*.dat"))):
        name = os.path.splitext(os.path.basename(p))[0]
        st1, st2, cert, rss, data = parse(p)
        y = data[:, 0]
        x = data[:, 1]
        f = M.get(name)
        if name == "Nelson":
            x1, x2 = data[:, 1], data[:, 2]
            f = None
            fun = lambda b: b[0] - b[1] * x1 * np.exp(-b[2] * x2) - np.log(y)
        else:
            fun = lambda b, f=f: f(b, x) - y
        for k, st in enumerate([st1, st2]):
            with np.errstate(all="ignore"):
                try:
                    r = least_squares(fun, np.array(st, float), method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=100000)
                    b = r.x
                    cost = float(np.sum(fun(b) ** 2))
                except Exception:
                    b = np.full(len(cert), np.nan); cost = np.nan
            lp = min(lre(e, c) for e, c in zip(b, cert))
            lr = lre(cost, rss)
            total += 1
            four += lp >= 4 and lr >= 4
            print(f"{name:<10} {k + 1:>5} {lp:>8.1f} {lr:>8.1f}")
    print(f"{four} of {total} fits reach 4+ certified digits in every parameter and the RSS")


main()
