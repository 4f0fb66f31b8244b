"""
``parastokes tune``: choosing the coarse solver
===============================================

``parastokes tune CONFIG --cores N --target ETA --out TUNED.toml`` searches the coarse solvers
this package can build (schemes, Lagrange nodes, Richardson steps, coarse grids, steps) for the
one with the highest predicted speedup (eq. 14) that is stable and reaches the target error η*
(eq. 34) on N cores, from measurements on a short pilot window (docs/tuning.md). Here it tunes
the quick rod swimmer of section 5.1.1 (``experiments/quick/s511_plain.toml``) for 8 cores and
η* = 1e-8, in a narrow space: forward Euler, Lagrange nodes in ε (2 or 3 of them), with and
without a Richardson step.
"""

# %%
# Run the command
# ---------------
# ``parastokes.cli.main`` is the command line as a function; it returns the exit status.
import json
import tempfile
import tomllib
from pathlib import Path

import matplotlib.pyplot as plt

import parastokes
from parastokes import cli

experiments = Path(parastokes.__file__).parents[1] / "experiments"  # of the repository
out = Path(tempfile.mkdtemp()) / "TUNED.toml"
status = cli.main(["tune", str(experiments / "quick" / "s511_plain.toml"), "--cores", "8",
                   "--target", "1e-8", "--out", str(out), "--schemes", "euler",
                   "--parameters", "epsilon", "--nodes", "2", "3", "--richardson", "0", "1"])
assert status == 0

# %%
# What it wrote
# -------------
# ``TUNED.toml`` is the input configuration with the chosen ``[coarse]``, ready for
# ``parastokes run``; ``TUNED.json`` holds every candidate's measurements and predictions.
tuned = tomllib.loads(out.read_text())
report = json.loads(out.with_suffix(".json").read_text())
chosen, baseline = report["chosen"], report["baseline"]
print("chosen [coarse]:", tuned["coarse"])
print(f"predicted speedup {chosen['predicted']['speedup']:.2f} with N_it = "
      f"{chosen['predicted']['iterations']}, against {baseline['predicted']['speedup']:.2f} for "
      f"the plain solver ({report['extrapolation']['note']})")

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4), layout="constrained")
accepted = [c for c in [baseline, *report["candidates"]] if c["status"] == "accepted"]
for cand in accepted:
    style = dict(marker="*", ms=16, color="C3", zorder=3) if cand == chosen else \
        dict(marker="s", ms=8, color="k") if cand == baseline else dict(marker="o", color="C0")
    right.plot(cand["predicted"]["gamma_ratio"], cand["pilot"]["eta1"], ls="", **style)
right.set(xlabel="cost γ_G / γ_F", ylabel="η¹ on the pilot window", yscale="log",
          title="accepted candidates (★ chosen, ■ plain)")
curves = report["curves"]
for label, speedups in curves["speedup"].items():
    is_chosen = label.startswith(chosen["label"] + " @")
    is_plain = label.startswith(baseline["label"] + " @")
    left.step(curves["targets"], speedups, where="mid", lw=3 if is_chosen else 1,
              color="C3" if is_chosen else "k" if is_plain else "0.75",
              ls="--" if is_plain else "-", zorder=3 if is_chosen or is_plain else 1)
left.axvline(1e-8, color="C3", lw=0.8, ls=":")
left.set(xscale="log", xlabel="target error η*", ylabel="predicted speedup on 8 cores",
         title="chosen (red), plain (dashed), others (grey)")
left.invert_xaxis()
plt.show()
