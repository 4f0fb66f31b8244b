"""A user's body that breaks the System contract (issue 32, items 1-3 and 13): each mistake is
one line naming the method, what it returned and what is expected, in ``check_system``, in
``parastokes check`` and in a run, which refuses it before its workers start (exit 2).
The broken bodies are in tests/user_beads.py; the fault table is in docs/validation.md."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import user_beads as ub

from parastokes import cli, config, integrate, models
from parastokes.bodies.contract import BodyError, array, probe
from parastokes.scene import Scene
from parastokes.testing import check_system

#: variant -> (the method named, what it found, what is expected)
FAULTS = {
    "OneRowShort": ("forces(state)", "shape (7, 3)", "expected (8, 3)"),
    "Flat": ("forces(state)", "shape (24,)", "expected (8, 3)"),
    "Transposed": ("forces(state)", "shape (3, 8)", "expected (8, 3)"),
    "NaNForces": ("forces(state)", "NaN (24 of 24 values", "expected finite values"),
    "TextForces": ("forces(state)", "dtype <U1", "expected real numbers"),
    "NoStateArgument": ("forces()", "cannot be called as forces(state)",
                        "expected def forces(self, state)"),
    "RatesWithoutTime": ("rates(state)", "cannot be called as rates(t, state)",
                         "expected def rates(self, t, state)"),
    "ShortRates": ("rates(t, state)", "shape (7, 3)", "with 8 rows"),
    "ShortAdvance": ("advance(state, rates, dt)", "shape (7, 3)", "expected (8, 3)"),
    "TextMonitor": ("monitor(state)", "'small'", "expected a real number"),
}


def _named(text: str, name: str) -> None:
    method, found, expected = FAULTS[name]
    assert f"{name}.{method}" in text and found in text and expected in text, text


def test_the_correct_body_keeps_the_contract():
    check_system(ub.Beads(), horizon=0.5)


@pytest.mark.parametrize("name", sorted(FAULTS))
def test_check_system_names_the_method_the_shape_found_and_expected(name):
    """On main, OneRowShort passed, Flat ended in a numba TypingError, Transposed in 'every scheme
    blows up', NaNForces in 'all rates vanish', the signatures in a bare TypeError."""
    with pytest.raises(AssertionError) as caught:
        check_system(getattr(ub, name)())
    text = str(caught.value)
    assert text.startswith(f"check_system({name}): ") and "\n" not in text
    _named(text, name)


def test_forces_are_checked_where_they_enter_without_the_probe():
    """The fluid sums with check=False: forces one row short gave wrong rates silently. Now the
    Python loop and a scene refuse them at the first evaluation."""
    body = ub.OneRowShort()
    with pytest.raises(BodyError, match=r"OneRowShort\.forces\(state\) returned shape \(7, 3\)"):
        integrate.run(body, body.initial_state(), 0.0, 0.1, "rk2", 0.01)
    scene = Scene((body,), viscosity=1.0, shear_rate=1.0)
    with pytest.raises(BodyError, match=r"OneRowShort\.forces\(state\)"):
        scene.rates(0.0, scene.initial_state())

    class ShortLoads(ub.Beads):  # a body's own loads, as a scene and the flow take them
        def loads(self, t, state):
            return self.forces(state), np.zeros((2, 3))

    scene = Scene((ub.Beads(), ShortLoads()), viscosity=1.0, shear_rate=1.0)
    with pytest.raises(BodyError, match=r"ShortLoads\.loads\(t, state\)\[1\] returned shape "
                                        r"\(2, 3\); expected \(8, 3\): torques"):
        scene.rates(0.0, scene.initial_state())



def test_a_fluid_body_calling_its_fluid_directly_is_told_the_shapes():
    """A body on FluidBody (not PointsInShear) that calls ``self.fluid.velocity`` itself: the
    sums run with check=False, so forces one row short were read past their end; the fluid
    value now compares the shapes (points, forces, torques) and names them."""

    class OwnRates(ub.Beads):
        def rates(self, t, state):
            return self.fluid.velocity(state, self.forces(state)[:-1], epsilon=self.epsilon)

    body = OwnRates()
    with pytest.raises(ValueError, match=r"fluid.velocity: forces of shape \(7, 3\); expected "
                                         r"\(8, 3\)"):
        body.rates(0.0, body.initial_state())
    with pytest.raises(ValueError, match=r"torques of shape \(3, 8\)"):
        body.fluid.velocity(body.initial_state(), body.forces(body.initial_state()),
                            epsilon=0.3, torques=np.zeros((3, 8)))
    x = body.initial_state()  # the right shapes: the same numbers as PointsInShear.rates
    u = body.fluid.velocity(x, body.forces(x), epsilon=0.3)
    u[:, 0] += body.shear_rate * x[:, 2]
    assert np.array_equal(u, ub.Beads().rates(0.0, x))


def test_values_the_package_can_use_pass_unchanged():
    """A float64 array is passed on as is (the same object: no copy, the same bits); other
    real numbers are converted to float64."""
    body = ub.Beads()
    x = body.initial_state()
    forces = body.forces(x)
    assert array(body, "forces(state)", forces, shape=(8, 3)) is forces
    assert np.array_equal(body.rates(0.0, x), body.fluid.velocity(x, forces, epsilon=0.3)
                          + np.outer(x[:, 2], [1.0, 0.0, 0.0]))

    class IntegerForces(ub.Beads):
        def forces(self, state):
            return np.rint(super().forces(state)).astype(np.int64)

    integer = IntegerForces()
    assert integer.checked_forces(x).dtype == np.float64
    assert np.array_equal(integer.checked_forces(x), np.rint(forces))


def test_a_body_error_crosses_processes_whole():
    error = pickle.loads(pickle.dumps(BodyError("X.forces(state) returned ...", "X.forces")))
    assert str(error) == "X.forces(state) returned ..." and error.method == "X.forces"


def test_a_late_nan_is_a_blow_up_naming_the_method():
    """NaN during a run (after the probe at the initial state passed) stays a blow-up with the
    last good state, and its reason names the method that returned it there."""
    body = ub.LateNaN()
    probe(body)
    with pytest.raises(integrate.BlowUpError,
                       match=r"non-finite state; LateNaN\.rates\(t, state\) returned NaN at the "
                             r"last good state \(t = 0\.05\)") as caught:
        integrate.run(body, body.initial_state(), 0.0, 0.2, "euler", 0.01)
    assert caught.value.step == 5 and np.isfinite(caught.value.last_state).all()


def test_a_points_in_shear_body_without_target_blocks_is_told_how_to_declare_it():
    from dataclasses import dataclass

    from parastokes.bodies.base import PointsInShear

    @dataclass(frozen=True)
    class NoBlocks(PointsInShear):
        epsilon: float = 0.3
        viscosity: float = 1.0
        shear_rate: float = 0.0
        n_threads: int | None = None

        def initial_state(self):
            return ub.Beads().initial_state()

        def forces(self, state):
            return -state

    with pytest.raises(BodyError, match=r"NoBlocks\.target_blocks is missing .* "
                                        r"field\(default=None, init=False\)"):
        probe(NoBlocks())


# ---- the command line: check and run ----------------------------------------------------------
#: The rest of a small run's configuration, after its ``[model]``.
RUN = """
[time]
t1 = 0.1

[fine]
dt = 0.01

[coarse]
dt = 0.05

[parareal]
n_slices = 2

[execution]
executor = "{executor}"
{workers}
"""
CONFIG = '[model]\nkind = "user_beads:{name}"\n' + RUN


def _config(folder: Path, name: str, executor: str = "serial") -> Path:
    path = folder / f"{name}.toml"
    workers = "workers = 2" if executor == "processes" else ""
    path.write_text(CONFIG.format(name=name, executor=executor, workers=workers))
    return path


def _error_lines(capsys) -> list[str]:
    return [line for line in capsys.readouterr().err.splitlines() if line.strip()]


@pytest.mark.parametrize("name", ["OneRowShort", "Flat", "Transposed", "NaNForces",
                                  "NoStateArgument", "TextForces"])
def test_parastokes_check_calls_a_users_body_and_names_the_fault(tmp_path, capsys, name):
    """On main, check said ok to every one of these (it never called the body)."""
    path = _config(tmp_path, name)
    assert cli.main(["check", str(path)]) == 2
    (line,) = _error_lines(capsys)
    assert line.startswith(f"{path}: {name}.")
    _named(line, name)


def test_check_goes_on_to_the_next_file_and_accepts_the_correct_body(tmp_path, capsys):
    broken, good = _config(tmp_path, "Flat"), _config(tmp_path, "Beads")
    assert cli.main(["check", str(broken), str(good)]) == 2
    out = capsys.readouterr()
    assert f"{good}: ok (user_beads:Beads, 8 points" in out.out
    assert f"{broken}: Flat.forces(state)" in out.err


@pytest.mark.parametrize("name", ["OneRowShort", "NoStateArgument", "NaNForces"])
def test_a_run_refuses_a_broken_body_before_its_workers_start(tmp_path, capsys, name):
    """On main: exit 0 with wrong rates; 'unexpected error' and a worker traceback (exit 1);
    a run of NaN. Now exit 2, the same line as check's, and no run directory (the body is
    called before the directory is claimed and the process pool started)."""
    path = _config(tmp_path, name, "processes")
    out = tmp_path / "out"
    assert cli.main(["run", str(path), "--out", str(out), "-q"]) == 2
    (line,) = _error_lines(capsys)
    assert line.startswith(f"error: {name}.")
    _named(line, name)
    assert not out.exists()


def test_a_body_error_in_a_worker_is_exit_2_in_one_line(capsys):
    """A body that breaks the contract only later, in a worker's task, is reported as the body's
    error (exit 2), not as a failed task to resume (exit 4)."""
    from parastokes.parallel import TaskError

    error = TaskError("fine solve of slice 2", BodyError("X.rates(t, state) returned shape (7, 3)"
                                                         "; expected 2-dimensional with 8 rows"))
    assert cli.exit_code(error) == 2
    assert cli.report(error, cli.Console(quiet=False)) == 2
    assert _error_lines(capsys) == ["error: X.rates(t, state) returned shape (7, 3); expected "
                                    "2-dimensional with 8 rows"]


# ---- item 13: the chain on the wall ------------------------------------------------------------
CHAIN = ("[model]\nkind = \"chain\"\nn_beads = 6\nwall = true\nheight = {height}\n"
         "tilt = {tilt}\n" + RUN.format(executor="serial", workers=""))


@pytest.mark.parametrize(("height", "tilt", "low"), [(0.0, 0.0, "0"), (1.0, 0.5, "-0.198")])
def test_check_and_run_refuse_a_chain_started_on_the_wall_alike(tmp_path, capsys, height, tilt,
                                                                 low):
    """On main, check accepted ``wall = true, height = 0`` that run refused."""
    path = tmp_path / "chain.toml"
    path.write_text(CHAIN.format(height=height, tilt=tilt))
    with pytest.raises(config.ConfigError) as caught:
        config.load(path)
    (issue,) = caught.value.issues
    assert issue[0] == "model" and f"its lowest bead is at z = {low}" in issue[1]
    assert cli.main(["check", str(path)]) == 2
    checked = capsys.readouterr().err
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out"), "-q"]) == 2
    ran = capsys.readouterr().err
    assert issue[1] in checked and issue[1] in ran
    assert not (tmp_path / "out").exists()


def test_a_chain_above_the_wall_is_accepted(tmp_path):
    path = tmp_path / "chain.toml"
    path.write_text(CHAIN.format(height=1.0, tilt=0.0))
    cfg, _ = config.load(path)
    assert cfg.model.build().initial_state()[:, 2].min() == 1.0


# ---- item 4: the vesicle factory takes the center the docs give it ---------------------------
def test_the_vesicle_factory_takes_a_center():
    """docs/bodies.md: ``center`` moves the sphere (on main: TypeError); the same sphere,
    translated, whose rates are the shear's at its new height plus the same relative motion."""
    at_origin = models.vesicle(subdivisions=1)
    moved = models.vesicle(subdivisions=1, center=(1.0, -2.0, 3.0))
    x0, x1 = at_origin.initial_state(), moved.initial_state()
    assert np.allclose(x1 - x0, [1.0, -2.0, 3.0], rtol=0, atol=1e-15)
    u0, u1 = at_origin.rates(0.0, x0), moved.rates(0.0, x1)
    shift = np.zeros_like(u0)
    shift[:, 0] = at_origin.shear_rate * 3.0
    assert np.allclose(u1, u0 + shift, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="center: need three coordinates"):
        models.vesicle(center=(1.0, 2.0))
