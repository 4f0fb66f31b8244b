"""The bacterium's sign conventions (docs/bodies.md, "Bacterium: sign conventions"): by default
E. coli's, a left-handed flagellum turning counter-clockwise seen from behind, so that the cell
swims head first and circles clockwise seen from above a wall (Lauga, DiLuzio, Whitesides &
Stone, Biophys. J. 90, 400 (2006))."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from parastokes import config
from parastokes.kinds.rigid import Bacterium, Helix, rotation
from parastokes.kinds.rigid.kind import BacteriumModel

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
#: The shipped bacterium configurations (each quick variant inherits its base's body).
CONFIGS = ["bacterium_wall.toml", "bacterium_circles.toml", "quick/bacterium_wall.toml",
           "quick/bacterium_circles.toml"]


def torsion_signs(points: np.ndarray) -> np.ndarray:
    """The sign of the discrete torsion of a polyline at each of its points: the triple product
    of three successive chords, positive on a right-handed curve, negative on a left-handed
    one (independent of the curve's parametrization and of the frame's orientation)."""
    d = np.diff(points, axis=0)
    return np.sign(np.einsum("ij,ij->i", np.cross(d[:-2], d[1:-1]), d[2:]))


def test_torsion_sign_tells_a_right_from_a_left_handed_helix():
    # a right-handed screw: (cos t, sin t, c t) about z, c > 0 (torsion c / (1 + c^2) > 0)
    t = np.linspace(0.0, 6 * math.pi, 200)
    screw = np.stack([np.cos(t), np.sin(t), 0.3 * t], axis=1)
    assert (torsion_signs(screw) > 0).all()
    assert (torsion_signs(screw * [1, 1, -1]) < 0).all()  # its mirror image
    assert (torsion_signs(np.array(Helix(handedness=1).points())) > 0).all()
    assert (torsion_signs(np.array(Helix(handedness=-1).points())) < 0).all()


def test_the_default_bacterium_has_a_left_handed_flagellum():
    for shape in (BacteriumModel(kind="bacterium").surface_shape(), Bacterium()):
        tail = shape.points(0.0)[shape.head_rows:]
        assert (torsion_signs(tail) < 0).all()
        assert shape.motor_rate < 0  # about -e1: counter-clockwise seen from behind


@pytest.mark.parametrize("name", CONFIGS)
def test_the_shipped_bacteria_are_e_coli(name):
    cfg, _ = config.load(EXPERIMENTS / name)
    shape = cfg.model.surface_shape()
    assert (torsion_signs(shape.points(0.0)[shape.head_rows:]) < 0).all()
    assert shape.motor_rate < 0


def swim(model: BacteriumModel, turns: int = 10, steps_per_turn: int = 20):
    """RK2 over ``turns`` motor turns: the centre's displacement in the initial heading's
    frame and the mean z component of the heading's angular velocity (rad/s)."""
    body = model.build()
    x = body.initial_state()
    heading = rotation.matrix(x[0, 3:7])[:, 0]
    dt = 2 * math.pi / abs(model.motor_rate) / steps_per_turn
    omega_z = []
    for _ in range(turns * steps_per_turn):
        k1 = body.rates(0.0, x)
        omega_z.append(k1[0, 5])
        x = body.advance(x, body.rates(0.0, body.advance(x, k1, dt / 2)), dt)
    moved = x[0, :3] - np.array(model.position)
    return moved @ heading, float(np.mean(omega_z))


def test_the_default_bacterium_swims_head_first_and_circles_clockwise_above_a_wall():
    """Ten motor turns of a coarse default bacterium 0.25 um above the wall: the centre moves
    along the heading e1 (head first), and the heading turns clockwise seen from above (its
    azimuth decreases: mean Ω_z < 0), at about 3 deg/s for a 10 Hz motor. Its mirror image, a
    right-handed flagellum turning the other way, swims head first too but circles the other
    way: the sense comes from the chirality, not the discretization."""
    common = {"kind": "bacterium", "head_points": 40, "tail_points": 24, "wall": True,
              "position": [0.0, 0.0, 0.75]}
    forward, omega_z = swim(BacteriumModel(**common))
    assert forward > 0.5  # um over 1 s: head first
    assert math.degrees(omega_z) < -1.0  # deg/s: clockwise seen from above
    mirror = BacteriumModel(**common, handedness=1, motor_rate=2 * math.pi * 10)
    forward_m, omega_m = swim(mirror)
    assert forward_m > 0.5
    assert math.degrees(omega_m) > 1.0
