"""A complete SYNTHETIC surrogate bundle (closed-form laws, not DPD) for development and tests.

:func:`write_synthetic_bundle` writes a bundle directory in the format of
:mod:`bubblecal.surrogates.bundle` with

* six mechanical MLP surrogates, one per reference curve and at its measured geometry
  (Definity compression 2.1 / 2.9 / 3.0 um; SonoVue indentation 3.2 / 3.4 / 5.8 um, data diameters
  3.19 / 3.40 / 5.76 um, radius_dpd = D / 0.5 um), each a tiny tanh MLP fitted in seconds (L-BFGS on the
  squared *relative* error, numpy/scipy) to the closed-form laws of
  :mod:`bubblecal.surrogates.training.synthetic`, over a parameter box (:data:`TRAINING_BOXES`) that contains
  every shipped prior box of the agent (full, reduced and reduced_acoustic workflows; the test
  ``tests/surrogates/test_synthetic_bundle.py`` checks this) and a loading coordinate range from 0 to
  :data:`X_MARGIN` times the largest value of the reference curve. k_a and k_b are sampled
  log-uniformly (they span decades). The indentation law is softly saturated at
  delta_max = :data:`DEPTH_CAP_RADII` x R, delta -> delta / (1 + (delta/delta_max)^4)^(1/4) (< 1 % change
  below 0.4 delta_max, which covers the reference depths), so that a tiny network need not learn
  depths larger than the bubble that the softest corner of the SonoVue box produces;
* two acoustic surrogates (``definity``, ``sonovue``): f_res^2(k_a) quadratics fitted at every observed
  acoustic diameter of the agent plus a 0.25 um grid (for plots), to frequencies of the ringdown law of
  docs/physics.md section 6, check 7,

      omega_0^2 = (16 pi k_a + 12 pi R p_g) / M_shell      [DPD: k_a 2-D modulus, R length, p_g pressure]

  with M_shell = rho_shell h 4 pi R^2 (the real shell mass, rho_shell = 1100 kg/m^3, h from the unit
  system, converted to DPD mass), p_g = :data:`GAS_PRESSURE_DPD` (the published back pressure, a stand-in
  for the gas pressure) and f = omega_0 / (2 pi u_t) converted to MHz by :mod:`bubblecal.data.units`
  (with the real shell mass no ringdown mass factor is involved).

Every file's metadata and the manifest notes say "SYNTHETIC closed-form laws, for development/tests,
not DPD". Posteriors obtained with this bundle are NOT physical results.

Units: DPD throughout (compression x = displacement [DPD length], y = force [DPD force]; indentation
x = force [DPD force], y = depth [DPD length]); acoustic frequencies in MHz, k_a in DPD units.
"""

from __future__ import annotations

import contextlib
import ctypes
import math
import time
from pathlib import Path

import numpy as np

from bubblecal.data import DEFAULT_UNITS, REFERENCE_CURVES, SHELL_PARAMETERS, UnitSystem, load_reference
from bubblecal.surrogates.acoustic import AcousticSurrogate
from bubblecal.surrogates.axes import X_INFO, Y_INFO
from bubblecal.surrogates.bundle import default_bundle_path
from bubblecal.surrogates.bundle_write import write_bundle
from bubblecal.surrogates.mlp import mlp_forward, xavier_uniform_weights
from bubblecal.surrogates.surrogate_file import save_surrogate
from bubblecal.surrogates.training.dataset import TrainingSet
from bubblecal.surrogates.training.synthetic import truth

__all__ = ["development_bundle_path", "SYNTHETIC_NOTE", "TRAINING_BOXES", "LOG_PARAMETERS", "X_MARGIN",
           "DEPTH_CAP_RADII", "GAS_PRESSURE_DPD", "RHO_SHELL_KG_M3", "ACOUSTIC_KA_RANGE", "ACOUSTIC_GRID_UM",
           "ringdown_frequency_MHz", "write_synthetic_bundle", "is_synthetic_bundle"]

#: The loud warning carried by the manifest and every file of the bundle.
SYNTHETIC_NOTE = ("SYNTHETIC closed-form laws, for development/tests, not DPD: surrogates trained on "
                  "bubblecal.surrogates.training.synthetic (mechanics) and the ringdown law of docs/physics.md "
                  "section 6 check 7 (acoustics); posteriors obtained with this bundle are not physical results.")

#: Training boxes [lo, hi] per agent (DPD units; b1..a4 dimensionless). Each contains the union of the
#: agent's shipped prior boxes (priors/<agent>_{full,reduced,reduced_acoustic}.toml), widened slightly.
TRAINING_BOXES: dict[str, dict[str, tuple[float, float]]] = {
    "definity": {"ka": (3.4e3, 3.5e4), "kb": (95.0, 1150.0), "b1": (0.0, 3.0), "b2": (0.0, 10.0),
                 "a3": (-2.5, 3.0), "a4": (0.0, 4.0)},
    "sonovue": {"ka": (5.5e2, 5.7e5), "kb": (95.0, 7.2e4), "b1": (0.0, 3.0), "b2": (0.0, 10.0),
                "a3": (-2.5, 3.0), "a4": (0.0, 4.0)},
}
#: Parameters sampled log-uniformly in training (they span decades).
LOG_PARAMETERS = ("ka", "kb")
#: The loading coordinate is trained on [0, X_MARGIN * max x of the reference curve].
X_MARGIN = 1.25
#: Indentation depths are softly saturated at this many bubble radii (module docstring).
DEPTH_CAP_RADII = 0.5
#: Gas pressure in the ringdown law [DPD pressure] (the published constant back pressure p_b = 91).
GAS_PRESSURE_DPD = 91.0
#: Shell density [kg/m^3] of the ringdown law's shell mass.
RHO_SHELL_KG_M3 = 1100.0
#: Acoustic fits: k_a range [DPD] per agent (contains the agent's prior boxes of k_a).
ACOUSTIC_KA_RANGE = {"definity": (3.4e3, 3.5e4), "sonovue": (5.5e2, 5.7e5)}
#: Acoustic fits: diameter grid [um] per agent (observed diameters are added).
ACOUSTIC_GRID_UM = {"definity": (4.0, 12.0), "sonovue": (2.0, 5.0)}


def ringdown_frequency_MHz(ka, diameter_um: float, units: UnitSystem = DEFAULT_UNITS,
                           gas_pressure_dpd: float = GAS_PRESSURE_DPD, rho_shell_kg_m3: float = RHO_SHELL_KG_M3):
    """Undamped ringdown frequency f_0 of the check-7 law, omega_0^2 = (16 pi ka + 12 pi R p_g) / M_shell.

    The law of docs/physics.md section 6, check 7, with the real shell mass (module docstring).

    Parameters
    ----------
    ka : array_like
        Stretching modulus [DPD 2-D modulus].
    diameter_um : float
        Bubble diameter [um].
    units : bubblecal.data.units.UnitSystem
        Unit system (radius, shell thickness, mass and time scales).
    gas_pressure_dpd : float
        Gas pressure p_g [DPD pressure].
    rho_shell_kg_m3 : float
        Shell density [kg/m^3].

    Returns
    -------
    numpy.ndarray
        f_0 [MHz], the shape of ``ka``.
    """
    radius = float(units.radius_dpd(diameter_um))
    area_m2 = 4.0 * math.pi * (radius * units.length_m) ** 2
    mass_dpd = rho_shell_kg_m3 * units.shell_thickness_m * area_m2 / units.mass_kg
    omega2 = (16.0 * math.pi * np.asarray(ka, dtype=float) + 12.0 * math.pi * radius * gas_pressure_dpd) / mass_dpd
    return units.angular_to_physical_Hz(np.sqrt(omega2)) / 1e6


def _lhs(rng: np.random.Generator, n: int, box: dict[str, tuple[float, float]]) -> np.ndarray:
    """(n, 6) Latin-hypercube parameter sets in ``box`` (log-uniform strata for :data:`LOG_PARAMETERS`)."""
    u = (rng.permuted(np.tile(np.arange(n), (6, 1)), axis=1).T + rng.random((n, 6))) / n
    cols = []
    for j, name in enumerate(SHELL_PARAMETERS):
        lo, hi = box[name]
        if name in LOG_PARAMETERS:
            cols.append(np.exp(np.log(lo) + u[:, j] * (np.log(hi) - np.log(lo))))
        else:
            cols.append(lo + u[:, j] * (hi - lo))
    params = np.stack(cols, axis=1)
    # pin the box corners of every parameter onto the first curves so that the training box is exact
    for j, name in enumerate(SHELL_PARAMETERS):
        params[2 * j % n, j], params[(2 * j + 1) % n, j] = box[name]
    return params


@contextlib.contextmanager
def _single_blas_thread():
    """Best effort: run numpy's OpenBLAS single-threaded inside the block; a no-op where it cannot be found.

    Tiny matrices run faster without thread hand-offs, notably on a loaded machine.
    """
    handles = []
    try:
        with open("/proc/self/maps") as fh:
            paths = sorted({line.split()[-1] for line in fh if "openblas" in line.lower() and ".so" in line})
        for path in paths:
            lib = ctypes.CDLL(path)
            for prefix in ("scipy_openblas", "openblas"):
                for suffix in ("64_", ""):
                    get = getattr(lib, f"{prefix}_get_num_threads{suffix}", None)
                    put = getattr(lib, f"{prefix}_set_num_threads{suffix}", None)
                    if get is not None and put is not None:
                        handles.append((put, int(get())))
                        put(1)
                        break
    except (OSError, AttributeError, ValueError):
        pass
    try:
        yield
    finally:
        for put, n in handles:
            put(n)


def _fit_mlp(u: np.ndarray, y: np.ndarray, hidden: tuple[int, ...], iterations: int, seed: int,
             rel_floor: float = 0.2):
    """Fit a standardised tanh MLP to ``(u, y)`` by L-BFGS (scipy) on the mean squared *relative* error.

    The residual of point j is (y_hat_j - y_j) / (|y_j| + rel_floor * median|y|); forward pass and
    gradient are written out in float64 numpy (no torch, no JAX tracing: a tiny network, a few thousand
    points). Returns (weights, biases, in_mean, in_std, out_mean, out_std, train_rel_rms) in the
    :mod:`bubblecal.surrogates.mlp` convention (W: (fan_in, fan_out)).
    """
    from scipy.optimize import minimize

    in_mean, in_std = u.mean(axis=0), u.std(axis=0)
    out_mean, out_std = np.array([y.mean()]), np.array([y.std()])
    z = (u - in_mean) / in_std
    t = (y - out_mean[0]) / out_std[0]
    weight = (out_std[0] / (np.abs(y) + rel_floor * np.median(np.abs(y)))) ** 2 / y.size
    w0, b0 = xavier_uniform_weights([u.shape[1], *hidden, 1], seed=seed, dtype=np.float64)
    shapes = [w.shape for w in w0] + [b.shape for b in b0]
    n_layers = len(w0)

    def unflat(flat):
        out, i = [], 0
        for shape in shapes:
            k = int(np.prod(shape))
            out.append(flat[i:i + k].reshape(shape))
            i += k
        return out[:n_layers], out[n_layers:]

    def value_and_grad(flat):
        ws, bs = unflat(flat)
        acts = [z]
        h = z
        for i in range(n_layers):
            h = h @ ws[i] + bs[i]
            if i < n_layers - 1:
                h = np.tanh(h)
            acts.append(h)
        r = h[:, 0] - t
        g = (2.0 * weight * r)[:, None]
        gw, gb = [None] * n_layers, [None] * n_layers
        for i in range(n_layers - 1, -1, -1):
            gw[i] = acts[i].T @ g
            gb[i] = g.sum(axis=0)
            if i > 0:
                g = (g @ ws[i].T) * (1.0 - acts[i] ** 2)
        return float(np.sum(weight * r * r)), np.concatenate([a.ravel() for a in gw + gb])

    flat0 = np.concatenate([a.ravel() for a in w0 + b0])
    with _single_blas_thread():
        res = minimize(value_and_grad, flat0, jac=True, method="L-BFGS-B",
                       options={"maxiter": iterations, "maxfun": 2 * iterations})
    ws, bs = unflat(res.x)
    return ([w.astype(np.float32) for w in ws], [b.astype(np.float32) for b in bs], in_mean, in_std, out_mean,
            out_std, float(np.sqrt(res.fun)))


def _law(setup: str, params, x, radius_dpd: float) -> np.ndarray:
    """The training law: :func:`bubblecal.surrogates.training.truth`, indentation depth softly saturated."""
    y = truth(setup, params, x, radius_dpd)
    if setup == "indentation":
        cap = DEPTH_CAP_RADII * radius_dpd
        y = y / (1.0 + (y / cap) ** 4) ** 0.25
    return y


def _reference_geometry():
    """(agent, setup, nominal D, measured D, x_max of the reference curve) per shipped curve."""
    out = []
    for name, (agent, kind, nominal, measured, _cite) in REFERENCE_CURVES.items():
        curve = load_reference(agent, nominal)
        out.append((agent, kind, float(nominal), float(measured), float(np.max(curve.x)), name))
    return out


def _mechanical(folder: Path, agent: str, setup: str, nominal: float, measured: float, x_max: float, *,
                n_curves: int, n_points: int, hidden: tuple[int, ...], iterations: int, seed: int,
                units: UnitSystem) -> tuple[Path, float]:
    """Fit and save one mechanical surrogate of the closed-form law; returns (file, holdout score)."""
    radius = float(units.radius_dpd(measured))
    rng = np.random.default_rng(seed)
    box = TRAINING_BOXES[agent]
    params = _lhs(rng, n_curves, box)
    x = np.linspace(0.0, X_MARGIN * x_max, n_points)
    y = _law(setup, params, x, radius)
    ts = TrainingSet(setup=setup, params=params, radius_dpd=np.full(n_curves, radius), x=np.tile(x, (n_curves, 1)),
                     y=y, curve_id=np.array([f"synthetic-bundle-{setup}-{nominal:g}-{i:05d}" for i in range(n_curves)]),
                     source=f"SYNTHETIC closed-form law bubblecal.surrogates.training.synthetic.{setup}, seed={seed}")
    u, target, _ = ts.points()
    t0 = time.perf_counter()
    w, b, im, isd, om, osd, rel = _fit_mlp(u, target, hidden, iterations, seed)
    # held-out check against the exact law on fresh parameter sets (median per-curve relative L2)
    test = _lhs(np.random.default_rng(seed + 1000), 64, box)
    uu = np.concatenate([np.repeat(test, n_points, axis=0), np.tile(x, 64)[:, None]], axis=1)
    pred = mlp_forward(w, b, im, isd, om, osd, uu, xp=np)[:, 0].reshape(64, n_points)
    exact = _law(setup, test, x, radius)
    holdout = float(np.median(np.linalg.norm(pred - exact, axis=1) / np.linalg.norm(exact, axis=1)))
    xname, xunits = X_INFO[setup]
    yname, yunits = Y_INFO[setup]
    md = {
        "setup": setup, "diameter_um": float(ts.diameter_um), "nominal_diameter_um": nominal, "radius_dpd": radius,
        "param_names": list(SHELL_PARAMETERS), "input_names": [*SHELL_PARAMETERS, xname],
        "input_units": ["DPD 2-D modulus", "DPD energy", "1", "1", "1", "1", xunits],
        "output_name": yname, "output_units": yunits,
        "param_ranges": {k: list(v) for k, v in ts.param_ranges().items()}, "x_range": list(ts.x_range()),
        "holdout_score": holdout,
        "holdout_metric": "median over 64 fresh parameter sets of ||y_hat - y_exact||_2 / ||y_exact||_2",
        "data_hash": ts.data_hash(),
        "architecture": {"hidden": list(hidden), "activation": "tanh", "output": "linear"},
        "training": {"optimizer": "L-BFGS-B (scipy), full batch", "iterations": iterations, "seed": seed,
                     "loss": "mean squared relative error (floor 20 % of the median |y|)",
                     "law": "synthetic.truth" + (f", depth saturated at {DEPTH_CAP_RADII} R"
                                                 if setup == "indentation" else ""),
                     "train_rel_rmse": rel, "n_curves": n_curves, "n_points": n_points,
                     "wall_s": time.perf_counter() - t0, "log_uniform": list(LOG_PARAMETERS)},
        "source": ts.source, "synthetic": True, "notes": SYNTHETIC_NOTE,
    }
    path = folder / f"{setup}_{nominal:g}um.npz"
    save_surrogate(path, w, b, im, isd, om, osd, md)
    return path, holdout


def _acoustic(folder: Path, agent: str, units: UnitSystem) -> Path:
    """Fit and save the agent's acoustic surrogate of the check-7 law; returns the file."""
    from bubblecal.data import acoustic_observations

    lo, hi = ACOUSTIC_GRID_UM[agent]
    diameters = {round(float(d), 2) for d in np.arange(lo, hi + 1e-9, 0.25)}
    diameters |= {round(o.diameter_um, 2) for o in acoustic_observations(agent)}
    ka = np.geomspace(*ACOUSTIC_KA_RANGE[agent], 25)
    data = {d: (ka, ringdown_frequency_MHz(ka, d, units)) for d in sorted(diameters)}
    sur = AcousticSurrogate.fit(data, name=agent, meta={
        "synthetic": True, "notes": SYNTHETIC_NOTE, "law": "omega0^2 = (16 pi ka + 12 pi R p_g) / M_shell",
        "gas_pressure_dpd": GAS_PRESSURE_DPD, "rho_shell_kg_m3": RHO_SHELL_KG_M3})
    return sur.save(folder / f"acoustic_{agent}.json")


def write_synthetic_bundle(path: str | Path, *, seed: int = 0, quick: bool = False,
                           units: UnitSystem = DEFAULT_UNITS, progress=None) -> Path:
    """Write the SYNTHETIC development bundle into directory ``path``.

    Surrogates are in DPD units (module docstring); acoustic ones in MHz vs k_a [DPD]. Holdout errors against
    the exact law are in the manifest notes.

    Parameters
    ----------
    path : str or Path
        Bundle directory (created when missing).
    seed : int
        Fixes the designs and the initial weights.
    quick : bool
        Test settings: 150 curves x 10 points, a 16x16 MLP, 1000 L-BFGS iterations per surrogate; default:
        400 curves x 16 points, 24x24, 4000 iterations.
    units : bubblecal.data.units.UnitSystem
        Unit system of the geometry and the acoustic law.
    progress : callable, optional
        Receives one line of text per file written.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    settings = (dict(n_curves=150, n_points=10, hidden=(16, 16), iterations=1000) if quick
                else dict(n_curves=400, n_points=16, hidden=(24, 24), iterations=4000))
    files, scores = [], {}
    for i, (agent, setup, nominal, measured, x_max, name) in enumerate(_reference_geometry()):
        f, score = _mechanical(path, agent, setup, nominal, measured, x_max, seed=seed + 17 * i, units=units,
                               **settings)
        files.append(f)
        scores[name] = score
        if progress:
            progress(f"{f.name}: holdout rel. L2 vs exact law {score:.3%}")
    acoustic = {agent: _acoustic(path, agent, units) for agent in ("definity", "sonovue")}
    if progress:
        progress(f"acoustic: {', '.join(p.name for p in acoustic.values())}")
    notes = (f"{SYNTHETIC_NOTE} quick={quick}, seed={seed}; holdout vs exact law: "
             + ", ".join(f"{k} {v:.2%}" for k, v in scores.items()))
    write_bundle(path, files, acoustic, notes=notes)
    return path


def development_bundle_path(quick: bool = False, cache_dir: str | Path | None = None) -> Path:
    """The shipped bundle when installed, else a SYNTHETIC one written once into ``cache_dir`` and reused.

    For notebooks and demos that must run without the shipped bundle.

    Parameters
    ----------
    quick : bool
        Settings of a bundle written here (:func:`write_synthetic_bundle`).
    cache_dir : str or Path, optional
        Folder of the synthetic bundle (default: the temp folder).

    Returns
    -------
    Path
        The bundle directory.
    """
    import tempfile

    shipped = Path(default_bundle_path())
    if (shipped / "manifest.json").is_file():
        return shipped
    folder = Path(cache_dir or tempfile.gettempdir()) / f"bubblecal_synthetic_bundle_{'quick' if quick else 'full'}"
    if not (folder / "manifest.json").is_file():
        write_synthetic_bundle(folder, quick=quick)
    return folder


def is_synthetic_bundle(bundle) -> bool:
    """Whether a bundle is SYNTHETIC (its manifest notes say so).

    Parameters
    ----------
    bundle : Bundle or dict
        A loaded :class:`~bubblecal.surrogates.Bundle` or its manifest.

    Returns
    -------
    bool
        True for a synthetic bundle.
    """
    manifest = getattr(bundle, "manifest", bundle)
    return "SYNTHETIC" in str(manifest.get("notes", ""))
