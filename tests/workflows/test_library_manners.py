"""Library manners: importing bubblecal and drawing a calibration's figures leave a notebook user's matplotlib
backend and rcParams as they were, and no pyplot figure open (the user's process is a subprocess here)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

#: The "user" session: a non-default backend and rcParams of their own, then every bubblecal module and a tiny
#: calibration with its figures and report; prints what changed as one JSON line.
USER_SESSION = r"""
import importlib, json, pkgutil, sys
import matplotlib
matplotlib.use("svg")
matplotlib.rcParams["lines.linewidth"] = 3.25
matplotlib.rcParams["font.size"] = 13.0
matplotlib.rcParams["axes.spines.top"] = True
before = {k: repr(v) for k, v in matplotlib.rcParams.items()}

import bubblecal
layers = ("data", "priors", "models", "surrogates", "sim", "campaigns", "inference", "workflows")
imported, missing = [], []
for name in ("bubblecal._lazy", "bubblecal._progress", *(f"bubblecal.{layer}" for layer in layers)):
    importlib.import_module(name)
    imported.append(name)
for layer in layers:
    package = importlib.import_module(f"bubblecal.{layer}")
    for info in pkgutil.walk_packages(package.__path__, f"bubblecal.{layer}."):
        if info.name.rsplit(".", 1)[-1] == "__main__":
            continue
        try:
            importlib.import_module(info.name)
            imported.append(info.name)
        except ModuleNotFoundError as exc:  # an optional extra that is not installed
            if exc.name and exc.name.split(".")[0] == "bubblecal":
                raise
            missing.append(f"{info.name} ({exc.name})")

from bubblecal.workflows.calibrate import CalibrationConfig, make_plan, run_calibration
config = CalibrationConfig(agents=("definity",), workflow="reduced", bundle=sys.argv[1], population=120,
                           out=sys.argv[2], phase2_samples=120, predictive_samples=100, num_mcmc_steps=2,
                           curves=("definity_compression_2.1um",), figures=True)
(result,) = run_calibration(make_plan(config))

after = {k: repr(v) for k, v in matplotlib.rcParams.items()}
open_figures = []
if "matplotlib.pyplot" in sys.modules:
    open_figures = sys.modules["matplotlib.pyplot"].get_fignums()
print(json.dumps({
    "backend": matplotlib.get_backend(),
    "changed": sorted(k for k in before.keys() | after.keys() if before.get(k) != after.get(k)),
    "open_figures": open_figures,
    "figures": [str(p) for p in result.figures],
    "imported": len(imported),
    "missing": missing,
}))
"""


def _user_session(bundle: Path, out: Path) -> dict:
    proc = subprocess.run([sys.executable, "-c", USER_SESSION, str(bundle), str(out)], capture_output=True,
                          text=True, timeout=900, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow  # a tiny calibration with figures in a fresh interpreter (JAX compiles its programs anew)
def test_user_backend_and_rcparams_survive_import_and_figures(tmp_path, synthetic_bundle):
    report = _user_session(synthetic_bundle, tmp_path / "cal")
    assert report["backend"] == "svg"
    assert report["changed"] == [], f"rcParams changed by bubblecal: {report['changed']}"
    assert report["open_figures"] == []
    # the figures were drawn (so the check covered them) and every module was imported
    assert {Path(p).name for p in report["figures"]} >= {"fit.png", "ka_kb.png", "population.png"}
    assert all(Path(p).stat().st_size > 10_000 for p in report["figures"])
    assert report["imported"] > 100 and not report["missing"], report


@pytest.mark.parametrize("folder", ["data", "priors", "models", "surrogates", "sim", "campaigns", "inference",
                                    "workflows"])
def test_library_code_selects_no_backend_and_sets_no_global_style(folder):
    """Static guard: library code never calls matplotlib.use, pyplot or a global rcParams/style setter (benchmark
    scripts, which are programs, may)."""
    banned = ("matplotlib.use(", "import matplotlib.pyplot", "from matplotlib import pyplot", "rcParams[",
              "rcParams.update(", "plt.style.use(", "matplotlib.style.use(", "mpl.use(", "mpl.rcParams")
    problems = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        if ".venv" in path.parts:
            continue
        text = path.read_text()
        problems += [f"{path.relative_to(ROOT)}: {b}" for b in banned if b in text]
    assert not problems, problems
