"""``bubblecal surrogates``: train, inspect and generate data for the mechanical surrogates.

Heavy imports (torch, jax) happen inside the commands so that ``bubblecal --help`` stays fast.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer

from bubblecal._extras import require
from bubblecal.data import AGENTS
from bubblecal.workflows.choices import Agent, LawFormName, LoadingProtocol, choice_value
from bubblecal.workflows.cli_train_options import band_list, int_list, log_input_names

app = typer.Typer(help="Neural (MLP) and acoustic surrogates: training, sweep, export, inspection.",
                  no_args_is_help=True, add_completion=False, pretty_exceptions_enable=False)


def _fail(msg: str, code: int = 1):
    """Print 'error: msg' on stderr and exit with status ``code``."""
    typer.echo(f"error: {msg}", err=True)
    raise typer.Exit(code)


@app.command("train")
def train(
    datasets: list[Path] = typer.Argument(..., metavar="DATASET...", help="Published-layout table (.csv/.dat) or "
                                           "campaign store (dir/.jsonl[.gz]); several are trained on together "
                                           "(e.g. a design and a denser slice of its box)."),
    setup: LoadingProtocol = typer.Option(..., "--setup", help="Loading protocol of the data."),
    diameter: float = typer.Option(None, "--diameter", help="Nominal bubble diameter [um] (names the files); must "
                                   "match the data's 2 x 0.25 um x median radius_dpd within 0.025 um. Not with "
                                   "--over-diameter."),
    over_diameter: bool = typer.Option(False, "--over-diameter/--per-diameter",
                                       help="One network over the sizes of the data (inputs + diameter, response over "
                                            "its size scale) instead of one per diameter."),
    ldo_bands: str = typer.Option("", "--ldo-bands", help="With --over-diameter: diameter bands held out whole, "
                                  "e.g. '3.0-3.4,5.0-5.4' \\[um] (leave-diameters-out score)."),
    log_inputs: str = typer.Option("auto", "--log-inputs", help="Shell parameters taken as natural logarithms: "
                                   "'auto' (ka,kb over the diameter; none per diameter, as published), 'none', "
                                   "or names, e.g. 'ka,kb'."),
    offgrid: Path = typer.Option(None, "--offgrid", help="Curves between the training grid's loading points (a store; "
                                 "'ok' curves): scored like the held-out ones; the selection takes the worst median."),
    out: Path = typer.Option(..., "--out", help="Output directory (surrogate .npz, reports, plot)."),
    sweep: bool = typer.Option(False, "--sweep/--no-sweep", help="Sweep widths x depths (else one architecture)."),
    widths: str = typer.Option("32,64,128,256", help="Sweep widths (comma separated)."),
    depths: str = typer.Option("2,3,4", help="Sweep depths (comma separated)."),
    width: int = typer.Option(64, help="Width without --sweep."),
    depth: int = typer.Option(3, help="Depth (hidden layers) without --sweep."),
    holdout_frac: float = typer.Option(0.1, help="Fraction of curves held out (grouped)."),
    seed: int = typer.Option(0, help="Seed of the holdout split, the pointwise split and the weights."),
    max_epochs: int = typer.Option(3000),
    patience: int = typer.Option(40, help="Epochs without validation improvement before lr /= 10."),
    max_reductions: int = typer.Option(3, help="Stop at the next stall after this many lr reductions."),
    batch_size: int = typer.Option(256),
    lr: float = typer.Option(1e-3),
    jobs: int = typer.Option(1, help="Architectures trained in parallel processes (1 torch thread each)."),
    curve_weights: str = typer.Option("none", "--curve-weights", help="How much each curve counts in the loss: "
                                      "'none' (the MSE over points) or 'capped' (a curve larger than the median "
                                      "one counts as much as it)."),
    device: str = typer.Option("cpu", help="Training device: cpu | cuda | cuda:N (same recipe; CUDA replays each "
                               "Adam step from a captured graph; several --jobs share one GPU)."),
    checkpoints: Path = typer.Option(None, "--checkpoints", help="Save each trained architecture here and reuse "
                                     "matching ones on a rerun (resume an interrupted sweep; default: "
                                     "OUT/checkpoints)."),
    zero_frac: float = typer.Option(0.01, help="Rupture: last raw response <= this fraction of the curve max."),
    max_drop: float = typer.Option(0.10, help="Rupture: drop below the running max > this fraction of the max."),
    failed_prefix: bool = typer.Option(True, "--failed-prefix/--no-failed-prefix",
                                       help="Campaign stores: keep the finite prefix (minus its last point) of "
                                            "'ruptured'/'failed' curves, NaN after the failure (no effect on "
                                            "published tables, which have no status)."),
    min_prefix_points: int = typer.Option(5, "--min-prefix-points", min=2,
                                          help="Points (x = 0 included) a kept failure prefix needs."),
    n_points: str = typer.Option("15", help="Loading points per row of a published table ('auto': infer)."),
    onnx: bool = typer.Option(True, "--onnx/--no-onnx", help="Also export ONNX and check onnxruntime parity."),
    quiet: bool = typer.Option(False, "--quiet", help="No progress bars."),
) -> None:
    """Train (optionally sweep) a surrogate on DATASET (one or more, trained on together) and export it with a report.

    Campaign stores: by default the intact prefix of 'ruptured'/'failed' curves is kept (the last
    finite point before failure dropped; see `filter_curves(keep_failed_prefix=True)`), so that the
    low-k_b corner, which ruptures on the loading grid, has training points; --no-failed-prefix keeps
    'ok' curves only.
    """
    import numpy as np

    from bubblecal.surrogates import load
    from bubblecal.surrogates.training import (
        MIN_SWEEP_CURVES,
        DatasetError,
        SweepConfig,
        TrainConfig,
        concat_training_sets,
        export_onnx,
        export_sweep,
        filter_curves,
        onnx_parity,
        read_dataset,
        run_sweep,
        scaled_max_rel_diff,
    )

    setup = choice_value(setup)
    # the [train] extra, before any data is read or network trained (ONNX only where it is exported)
    require("torch", "train")
    if onnx:
        require("onnx", "train")
        require("onnxruntime", "train")
    if over_diameter == (diameter is not None):
        raise typer.BadParameter("give --diameter D (one network per diameter) or --over-diameter, not both")
    if ldo_bands and not over_diameter:
        raise typer.BadParameter("--ldo-bands needs --over-diameter")
    bands = band_list(ldo_bands)
    logged = log_input_names(log_inputs)
    try:
        parts = []
        for dataset in datasets:
            part = read_dataset(dataset, setup=setup, n_points="auto" if n_points == "auto" else int(n_points))
            if part.setup != setup:
                _fail(f"{dataset}: holds {part.setup} data, --setup is {setup}")
            parts.append(part)
        raw = concat_training_sets(parts)
        dataset = " + ".join(str(d) for d in datasets)
        ts, report = filter_curves(raw, zero_frac=zero_frac, max_rel_drop=max_drop, keep_failed_prefix=failed_prefix,
                                   min_prefix_points=min_prefix_points)
        typer.echo(str(report))
        from bubblecal.surrogates import DIAMETER_ATOL_UM

        if not over_diameter and ts.n_curves and abs(ts.diameter_um - diameter) > DIAMETER_ATOL_UM:
            _fail(f"{dataset}: field 'radius_dpd' gives a diameter of {ts.diameter_um:g} um, "
                  f"--diameter is {diameter:g}")
        try:
            train_cfg = TrainConfig(lr=lr, batch_size=batch_size, max_epochs=max_epochs, patience=patience,
                                    max_reductions=max_reductions, threads=1, device=device,
                                    curve_weights=curve_weights)
        except ValueError as exc:
            raise typer.BadParameter(str(exc).replace("TrainConfig.device", "--device")
                                     .replace("TrainConfig.curve_weights", "--curve-weights")) from None
        inputs = {"inputs": "diameter", "ldo_bands": bands} if over_diameter else {}
        inputs["log_inputs"] = logged
        if sweep:
            cfg = SweepConfig(widths=int_list(widths, "--widths"), depths=int_list(depths, "--depths"),
                              holdout_frac=holdout_frac, seed=seed, jobs=jobs, train=train_cfg,
                              min_curves=MIN_SWEEP_CURVES, **inputs)
        else:
            cfg = SweepConfig(widths=(width,), depths=(depth,), holdout_frac=holdout_frac, seed=seed, jobs=1,
                              train=train_cfg, min_curves=2, **inputs)
        off = None if offgrid is None else filter_curves(read_dataset(offgrid, setup=setup, n_points="auto"))[0]
        result = run_sweep(ts, cfg, progress=not quiet, checkpoints=checkpoints or out / "checkpoints", offgrid=off)
    except (DatasetError, FileNotFoundError) as exc:
        _fail(str(exc))
    out.mkdir(parents=True, exist_ok=True)
    (out / "filter_report.json").write_text(json.dumps(report.as_dict(), indent=2))
    paths = result.write_report(out)
    d = ts.diameters_um
    stem = f"{ts.setup}_{d.min():g}-{d.max():g}um" if over_diameter else f"{ts.setup}_{diameter:g}um"
    npz = export_sweep(result, out / f"{stem}.npz", nominal_diameter_um=diameter, filter_report=report)
    sur = load(npz)
    # parity: the exported JAX function against torch on the held-out points (in the network's own target)
    torch = require("torch", "train")

    u, _, _, scale = result.holdout_set.network_points(result.inputs)  # raw: the surrogate's own call logs
    u_net = result.holdout_set.network_points(result.inputs, result.config.log_inputs)[0]
    with torch.no_grad():
        mod = result.best_model.torch_module(torch.float64)
        y_torch = mod(torch.as_tensor(u_net, dtype=torch.float64)).numpy()[:, 0]
    y_jax = np.asarray(sur(u[:, :6], u[:, 6], *([u[:, 7]] if over_diameter else []))) / scale
    checks = {"jax_vs_torch_max_rel_diff": scaled_max_rel_diff(y_jax, y_torch)}
    if onnx:
        onnx_path = export_onnx(result.best_model, out / f"{stem}.onnx")
        checks["onnx_vs_jax_max_rel_diff"] = onnx_parity(onnx_path, sur, u)["max_rel_diff"]
    summary = {"surrogate": str(npz), "selected": result.best, "holdout_score": result.score,
               "data_hash": result.data_hash, "filter": report.as_dict(), "parity": checks,
               "reports": {k: str(v) for k, v in paths.items()}, "sweep_wall_s": result.wall_s}
    (out / "train_summary.json").write_text(json.dumps(summary, indent=2, default=float))
    typer.echo(result.markdown())
    typer.echo(f"wrote {npz}")
    for k, v in checks.items():
        typer.echo(f"{k}: {v:.2e}")
    if any(v > 1e-5 for v in checks.values()):
        _fail("exported surrogate disagrees with the trained model beyond 1e-5 (see train_summary.json)")


@app.command("info")
def info(path: Path = typer.Argument(..., help="A surrogate .npz, an acoustic surrogate .json or a bundle "
                                               "directory.")) -> None:
    """Print the metadata of a surrogate file (mechanical or acoustic) or the contents of a bundle."""
    from bubblecal.surrogates import (
        AcousticFormatError,
        SurrogateFormatError,
        load,
        load_bundle,
        load_validation,
        validation_lines,
    )

    try:
        if path.suffix.lower() == ".json" and not path.is_dir():
            try:
                text = _acoustic_text(path)
            except (TypeError, AttributeError, KeyError, IndexError) as exc:  # a field of the wrong type
                raise AcousticFormatError(f"{path}: malformed acoustic surrogate ({type(exc).__name__}: {exc})") \
                    from None
            typer.echo(text)
        elif path.is_dir():
            b = load_bundle(path)
            figures = load_validation(path)
            if b.manifest.get("notes"):
                typer.echo(f"notes: {b.manifest['notes']}")
            listed = [(b.surrogates[key], None) for key in b.keys()]
            for setup in sorted(b.over_diameter.keys() | b.fast.keys()):  # each network over the diameter, its role
                listed += [((b.fast if role == "fast" else b.over_diameter)[setup], role) for role in b.networks(setup)]
            for sur, role in listed:
                md = sur.metadata
                typer.echo(repr(sur) + (f" [network: {role}]" if role else ""))
                ldo = "".join(f", {label} {md[key]:.3g}" for key, label in (("ldo_score", "leave-diameters-out"),
                              ("offgrid_score", "off the grid")) if md.get(key) is not None)
                typer.echo(f"  trained on {md.get('source', '?')}: {md.get('n_curves_train', '?')} curves "
                           f"({md.get('n_prefix_curves_train', 0)} failure-truncated prefixes), "
                           f"held-out median relative L2 {sur.holdout_score:.3g}{ldo}")
                for line in validation_lines(figures, sur.path.name if sur.path else ""):
                    typer.echo(line)
            for name, ac in list(b.acoustic.items()) + list(b.acoustic_law.items()):
                typer.echo(f"acoustic {name}: " + (_acoustic_law_text(ac) if hasattr(ac, "law") else
                                                   f"diameters {', '.join(f'{d:g}' for d in ac.diameters)} um"))
        else:
            sur = load(path)
            typer.echo(repr(sur))
            keys = ("param_ranges", "x_range", "diameter_range_um", "loading_range_per_size", "response_scale",
                    "ldo_score", "ldo_bands_um", "input_names", "input_units", "output_units", "source")
            typer.echo(json.dumps({k: sur.metadata[k] for k in keys if k in sur.metadata}, indent=2))
    except (SurrogateFormatError, AcousticFormatError, FileNotFoundError, ValueError) as exc:
        _fail(str(exc))


def _acoustic_law_text(sur) -> str:
    """One paragraph on an acoustic law: form, D and k_a ranges, hold-out errors."""
    law, h = sur.law, sur.law.holdout
    lo, hi = law.diameter_range
    ka_lo, ka_hi = law.ka_range
    bands = "; ".join(f"band {b['band_um'][0]:g}-{b['band_um'][1]:g} um held out: median {100 * b['median']:.2f} % "
                      f"max {100 * b['max']:.2f} %" for b in h.get("bands", []))
    return (f"law {sur.name!r}, form {law.form}: {law.law_form.expression()}\n"
            f"  diameter {lo:g}-{hi:g} um ({len(law.diameters_um)} simulated), ka {ka_lo:.6g}-{ka_hi:.6g} DPD, "
            f"{law.n_points} rows\n"
            f"  leave one diameter out: median {100 * h.get('median', float('nan')):.2f} % max "
            f"{100 * h.get('max', float('nan')):.2f} % (relative error of f_res)" + (f"; {bands}" if bands else ""))


def _acoustic_text(path: Path) -> str:
    """What `info` prints for an acoustic surrogate JSON (per-diameter quadratics or a law)."""
    from bubblecal.surrogates import AcousticSurrogate

    sur = AcousticSurrogate.load(path)
    if hasattr(sur, "law"):
        return _acoustic_law_text(sur)
    fits = [sur.fits[d] for d in sur.diameters]
    return (f"acoustic {sur.name!r}: one quadratic per diameter, {', '.join(f'{d:g}' for d in sur.diameters)} um; "
            f"LOO median {100 * float(np.median([f.loo_median for f in fits])):.2f} % max "
            f"{100 * float(np.nanmax([f.loo_max for f in fits])):.2f} %")


@app.command("synthetic")
def synthetic(
    out: Path = typer.Argument(..., help="Output CSV in the published row layout."),
    setup: LoadingProtocol = typer.Option("compression", "--setup", help="Loading protocol."),
    n_curves: int = typer.Option(400, "--n-curves"),
    diameter: float = typer.Option(2.1, "--diameter", help="Bubble diameter [um]."),
    noise: float = typer.Option(0.01, help="Relative (multiplicative) Gaussian noise per point."),
    seed: int = typer.Option(0),
) -> None:
    """Write a known-answer synthetic training set (closed-form shell force law + noise)."""
    from bubblecal.data import radius_dpd_from_diameter_um
    from bubblecal.surrogates.training import make_synthetic, write_published

    setup = choice_value(setup)
    ts = make_synthetic(n_curves, setup, radius_dpd=radius_dpd_from_diameter_um(diameter), noise=noise, seed=seed)
    write_published(ts, out)
    typer.echo(f"wrote {ts.n_curves} {setup} curves to {out}")


@app.command("synthetic-bundle")
def synthetic_bundle(
    out: Path = typer.Argument(..., help="Output directory of the bundle (created)."),
    seed: int = typer.Option(0, help="Seed of the designs and the initial weights."),
    quick: bool = typer.Option(False, "--quick", help="Smaller designs and networks (~10 s; for tests)."),
) -> None:
    """Write a SYNTHETIC development bundle (closed-form laws, not DPD): six mechanical + two acoustic surrogates."""
    from bubblecal.surrogates import write_synthetic_bundle

    write_synthetic_bundle(out, seed=seed, quick=quick, progress=typer.echo)
    typer.echo(f"wrote {out} -- SYNTHETIC closed-form laws, for development/tests, not DPD")


@app.command("acoustic")
def acoustic(
    stores: list[Path] = typer.Argument(..., help="Ringdown campaign store(s) of one agent (directory, .jsonl, "
                                                  ".jsonl.gz), e.g. from `bubblecal sim campaign definity_ringdown`."),
    out: Path = typer.Option(..., "--out", help="Acoustic surrogate JSON to write."),
    agent: Agent = typer.Option(None, "--agent", case_sensitive=False, help="Contrast agent (default: from the "
                                "campaign name)."),
    rows: Path = typer.Option(None, "--rows", help="Also write every fitted ringdown row (CSV)."),
    t_start: float = typer.Option(None, "--t-start", help="Fit R(t) only after this DPD time."),
    law: bool = typer.Option(False, "--law", help="Fit one law f_res(k_a, D) continuous in the diameter (file "
                             "format version 2) instead of one quadratic per diameter."),
    form: LawFormName = typer.Option(None, "--form", help="Form of the --law (default gas-coupled; "
                                     "docs/decisions.md)."),
) -> None:
    """Fit the acoustic surrogate from ringdown stores or row CSVs: one f_res^2(k_a) quadratic per diameter
    (LOO errors), or with --law one law continuous in the diameter (leave-diameters-out errors)."""
    from bubblecal.data import StoreError
    from bubblecal.workflows.acoustic_sweep import acoustic_law_from_stores, acoustic_surrogate_from_stores
    from bubblecal.workflows.console import fail

    agent, form = choice_value(agent), choice_value(form)
    for s in stores:
        if not s.exists():
            raise fail(f"{s}: no such ringdown store")
    if form is not None and not law:
        raise fail("--form needs --law")
    if law:
        try:
            sur, _ = acoustic_law_from_stores(stores, out, agent=agent, form=form, rows_csv=rows, t_start=t_start)
        except (ValueError, StoreError) as exc:
            raise fail(str(exc)) from None
        typer.echo(_acoustic_law_text(sur))
        typer.echo(f"wrote {out}" + (f" and {rows}" if rows else ""))
        return
    try:
        sur, sweeps = acoustic_surrogate_from_stores(stores, out, agent=agent, rows_csv=rows, t_start=t_start)
    except (ValueError, StoreError) as exc:
        raise fail(str(exc)) from None
    for s in sweeps:
        f = sur.fits[s.diameter_um]
        sm = s.summary()
        typer.echo(f"{s.diameter_um:6.2f} um: {sm['n_valid']}/{sm['n']} valid, check-7 ratio "
                   f"{sm['check7_ratio_median']:.4f}, LOO median {100 * f.loo_median:.2f} % "
                   f"max {100 * f.loo_max:.2f} %")
    typer.echo(f"wrote {out}" + (f" and {rows}" if rows else ""))


@app.command("bundle")
def bundle(
    out: Path = typer.Argument(..., help="Bundle directory to write (created; manifest.json + copies)."),
    surrogate: list[Path] = typer.Option(None, "--surrogate", help="A mechanical surrogate .npz (repeatable)."),
    fast: list[Path] = typer.Option(None, "--fast", help="A fast network over the diameter .npz (repeatable; "
                                    "manifest 'network': 'fast', what Bundle.get(..., network='fast') answers)."),
    acoustic: list[str] = typer.Option(None, "--acoustic", help="NAME=FILE.json of an acoustic surrogate "
                                                                "(repeatable; NAME definity or sonovue; per "
                                                                "name one per-diameter file and one law)."),
    notes: str = typer.Option("", "--notes", help="Free text stored in the manifest (provenance)."),
) -> None:
    """Assemble surrogates into a bundle directory (what `bubblecal calibrate --bundle DIR` reads)."""
    from bubblecal.surrogates import SurrogateFormatError, load_bundle, write_bundle
    from bubblecal.workflows.console import fail

    ac: dict[str, list[Path]] = {}
    for item in acoustic or []:
        name, sep, file = item.partition("=")
        if not sep or name not in AGENTS:
            raise fail(f"--acoustic {item!r}: expected definity=FILE or sonovue=FILE")
        ac.setdefault(name, []).append(Path(file))  # a name may have quadratics and a law
    missing = [str(p) for p in [*(surrogate or []), *(fast or []), *(f for fs in ac.values() for f in fs)]
               if not Path(p).is_file()]
    if missing:
        raise fail(f"no such file: {', '.join(missing)}")
    if not surrogate and not fast and not ac:
        raise fail("give at least one --surrogate, --fast or --acoustic")
    try:
        write_bundle(out, surrogate or [], ac, notes=notes, fast_files=fast or [])
        b = load_bundle(out)
    except (SurrogateFormatError, ValueError, OSError) as exc:
        raise fail(str(exc)) from None
    for (setup, d), s in sorted(b.surrogates.items()):
        typer.echo(f"{setup} {d:g} um: {s.architecture}, holdout {s.holdout_score}")
    for role, nets in (("accurate", b.over_diameter), ("fast", b.fast)):
        for setup, s in sorted(nets.items()):
            lo, hi = s.diameter_range_um
            typer.echo(f"{setup} {lo:g}-{hi:g} um (over the diameter, network: {role}): {s.architecture}, "
                       f"holdout {s.holdout_score}")
    for name, a in b.acoustic.items():
        typer.echo(f"acoustic {name}: {len(a.diameters)} diameters")
    for name, a in b.acoustic_law.items():
        typer.echo(f"acoustic {name}: law over {a.diameter_range[0]:g}-{a.diameter_range[1]:g} um")
    typer.echo(f"wrote {out / 'manifest.json'}")
