"""Tables of docs/validation.md, "Rigid and prescribed-motion bodies": errors against closed
forms as the surface is refined, and a torque-driven helix against resistive-force theory.

    PYTHONPATH=. python validation/rigid.py [--sizes 150 300 600 1200]

The studies are those of tests/test_rigid_validation.py (which asserts the fitted orders and
imports the helix study from here).
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from parastokes.kinds.rigid import Helix, RigidBody, Sphere, Squirmer
from parastokes.kinds.rigid.shapes import spacing


def speed(n: int, ratio: float, **kw) -> np.ndarray:
    shape = Sphere(1.0, n)
    body = RigidBody(shape=shape, epsilon=ratio * spacing(shape), viscosity=1.0, **kw)
    return body.rates(0.0, body.initial_state())[0, :6]


def rft_ratio(radius: float, pitch: float, filament: float) -> float:
    """U / (ΩR) of a force-free helix turned about its axis, resistive-force theory with Gray &
    Hancock's coefficients ξ_t = 2πμ/(ln(2λ/a) − 1/2), ξ_n = 4πμ/(ln(2λ/a) + 1/2)."""
    theta = math.atan(2 * math.pi * radius / pitch)
    xt = 2 * math.pi / (math.log(2 * pitch / filament) - 0.5)
    xn = 4 * math.pi / (math.log(2 * pitch / filament) + 0.5)
    s, c = math.sin(theta), math.cos(theta)
    return (xn - xt) * s * c / (xn * s * s + xt * c * c)


def helix_ratio(n: int, eps: float) -> float:
    """U / (ΩR) of the force-free rigid helix (radius 0.25, pitch 2, 4 turns, ``n`` centre-line
    points, regularization ``eps``) turned about its axis by an external torque, μ = 1."""
    body = RigidBody(shape=Helix(0.25, 2.0, 4.0, n), epsilon=eps, viscosity=1.0,
                     torque=(1.0, 0.0, 0.0))
    u = body.rates(0.0, body.initial_state())[0, :6]
    return float(u[0] / (u[3] * 0.25))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="*", default=[150, 300, 600, 1200])
    sizes = parser.parse_args().sizes
    print("| N | h | squirmer U/(2B1/3) − 1, B2 = 0 | same, B2 = 4 | sedimenting U/U_Stokes − 1 "
          "| turning Ω/Ω_Stokes − 1 |")
    print("|---|---|---|---|---|---|")
    rows = []
    for n in sizes:
        h = spacing(Sphere(1.0, n))
        sq = [speed(n, 0.3, slip=Squirmer(1.5, b2))[0] - 1.0 for b2 in (0.0, 4.0)]
        sed = -speed(n, 0.5, force=(0, 0, -6 * math.pi))[2] - 1.0
        turn = speed(n, 0.5, torque=(0, 0, 8 * math.pi))[5] - 1.0
        rows.append((h, sq[0], sed, turn))
        print(f"| {n} | {h:.4f} | {sq[0]:+.4f} | {sq[1]:+.4f} | {sed:+.4f} | {turn:+.4f} |")
    h, *errors = np.array(rows).T
    orders = [np.polyfit(np.log(h), np.log(np.abs(e)), 1)[0] for e in errors]
    print(f"| fitted order in h | | {orders[0]:.2f} | | {orders[1]:.2f} | {orders[2]:.2f} |")
    print()
    print("| ε | U/(ΩR), 400 points | U/(ΩR), 800 points | RFT (Gray & Hancock, a = ε) |")
    print("|---|---|---|---|")
    for eps in (0.03, 0.05):
        print(f"| {eps} | {helix_ratio(400, eps):.4f} | {helix_ratio(800, eps):.4f} | "
              f"{rft_ratio(0.25, 2.0, eps):.4f} |")


if __name__ == "__main__":
    main()
