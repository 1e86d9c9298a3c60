"""The phase store of a run folder: atomic phase files, ``manifest.json`` with config hashes, reuse.

Every phase carries a config hash that covers its data, priors, surrogate, sampler settings, seed and the
hashes of the phases it depends on (:func:`phase_hashes`). A phase whose file exists and whose hash in
the manifest matches is reused on rerun, so the hashed dicts decide which existing output folders are
reused: changing what they hold reruns every affected phase.
"""

from __future__ import annotations

import fnmatch
import hashlib
import json
import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from bubblecal.data import atomic_write
from bubblecal.inference.idata import IDATA_FORMAT
from bubblecal.workflows.calibrate.config import CalibrationConfig, phase2_samples, phase_tmcmc_options
from bubblecal.workflows.calibrate.phase_files import PhaseFileError, phase_format, read_phase, read_pointwise

__all__ = ["config_hash", "array_hash", "phase_hashes", "bundle_hashes", "PhaseStore", "PhaseFileError",
           "phase_dependencies"]


def config_hash(obj) -> str:
    """First 16 hex digits of the SHA-256 of ``obj`` as sorted-key JSON (non-JSON values via ``str``)."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def array_hash(*arrays) -> str:
    """First 16 hex digits of the SHA-256 of the arrays as contiguous little-endian float64."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(np.asarray(a, dtype="<f8")).tobytes())
    return h.hexdigest()[:16]


def phase_hashes(ap, config: CalibrationConfig, acoustic_hashes: Mapping[str, str]) -> dict[str, str]:
    """Config hash of every phase of one agent.

    Parameters
    ----------
    ap : bubblecal.workflows.calibrate.AgentPlan
        The agent's priors, curves, surrogates and acoustic datasets.
    config : CalibrationConfig
        Seed and TMCMC settings (:func:`~bubblecal.workflows.calibrate.phase_tmcmc_options`).
    acoustic_hashes : Mapping of str to str
        :func:`bundle_hashes` of the surrogate bundle (the acoustic surrogates' hashes).

    Returns
    -------
    dict of str to str
        ``phase1_<dataset>``, ``phase2`` and ``phase3_<dataset>`` -> 16-digit hash. Phase 1 covers its data,
        surrogate, priors and options; phase 2 the phase-1 hashes and its sample size; phase 3 its own
        phase-1 hash and the phase-2 hash.
    """
    spec_text = Path(ap.priors_path).read_text() if Path(ap.priors_path).is_file() else repr(ap.spec)
    o1, o23 = phase_tmcmc_options(config)
    common = {"agent": ap.agent, "workflow": ap.workflow, "priors": config_hash(spec_text), "seed": config.seed,
              "datasets": ap.dataset_names}
    hashes = {}
    for curve, sur in zip(ap.curves, ap.surrogates, strict=True):
        h1 = {**common, "phase": 1, "data": array_hash(curve.x, curve.y), "surrogate": sur.data_hash, "options": o1}
        if getattr(sur, "over_diameter", False):  # one network serves every size: the bound diameter is an input
            # networks of one training set share its data hash: the architecture tells them apart
            h1.update(diameter_um=float(sur.diameter_um), architecture=dict(sur.architecture))
            if getattr(sur, "log_inputs", ()):  # same data and layers with logged moduli: another network
                h1["log_inputs"] = list(sur.log_inputs)
        hashes[f"phase1_{curve.name}"] = config_hash(h1)
    for ds in ap.acoustic:
        hashes[f"phase1_{ds.name}"] = config_hash({**common, "phase": 1,
                                                   "data": array_hash(ds.diameter_um, ds.frequency_MHz),
                                                   "surrogate": _acoustic_hash(ap, acoustic_hashes),
                                                   "options": o1})
    p1 = [hashes[f"phase1_{n}"] for n in ap.dataset_names]
    hashes["phase2"] = config_hash({**common, "phase": 2, "upstream": p1, "options": o23,
                                    "phase2_samples": phase2_samples(config, len(ap.dataset_names))})
    for n in ap.dataset_names:
        h3 = {**common, "phase": 3, "self": hashes[f"phase1_{n}"], "upstream": hashes["phase2"], "options": o23}
        if config.phase3 != "published":  # keeps the hashes of runs with the published phase 3 unchanged
            h3["phase3"] = config.phase3
            # the leave-one-out weights come from the stacked phase-2 terms (equal to float round-off to the
            # per-dataset sum they replaced): files of the earlier computation are not reused
            h3["loo_weights"] = "stacked"
        if config.phase3_start != "prior":  # other draws than the path from the prior (the hashes before it)
            h3["phase3_start"] = config.phase3_start
        hashes[f"phase3_{n}"] = config_hash(h3)
    return hashes


def bundle_hashes(bundle) -> dict[str, str]:
    """``acoustic_<name>`` (per-diameter quadratics) and ``acoustic_law_<name>`` (law over the diameter) ->
    config hash of each acoustic surrogate of ``bundle`` (its JSON content)."""
    out = {}
    for name, ac in bundle.acoustic.items():
        out[f"acoustic_{name}"] = config_hash(ac.to_dict())
    for name, ac in getattr(bundle, "acoustic_law", {}).items():
        out[f"acoustic_law_{name}"] = config_hash(ac.to_dict())
    return out


def _acoustic_hash(ap, acoustic_hashes: Mapping[str, str]) -> str:
    """The :func:`bundle_hashes` entry of the acoustic surrogate the agent's plan uses (quadratics or law)."""
    key = "acoustic_law_" if hasattr(ap.f_res, "law") else "acoustic_"
    return acoustic_hashes.get(f"{key}{ap.acoustic_name}", "")


class PhaseStore:
    """Phase files of one agent/workflow folder plus ``manifest.json`` (config hash per phase).

    ``expected[name]`` holds the hash a phase must carry to be reused; :meth:`load` returns the stored
    :class:`~bubblecal.inference.phase_results.PhaseResult` when file and hash match (and not ``force``),
    :meth:`save` writes the file atomically and records it in the manifest.

    Parameters
    ----------
    folder : Path
        The run folder ``out/<agent>/<workflow>``.
    netcdf : bool
        Write ArviZ NetCDF (``.nc``), else ``.npz``; either suffix is read back.
    force : bool
        Never reuse a phase.
    run_info : Mapping or None
        Stored as the manifest's ``run`` entry (configuration, its hash, agent, priors, bundle).
    say : callable or None
        Receives one line per damaged phase file (the file named, and that it is recomputed).
    background : bool
        Write the files off the caller's thread (below).
    writers : int or None
        Writer processes of a background store (0: one thread; None: by the machine's cores,
        :func:`~bubblecal.workflows.calibrate.device.helper_processes`).

    A stored phase file that cannot be read (truncated, garbage) is not reused: that phase runs again, and so
    does every phase that depends on it (:func:`phase_dependencies`), while the others are still reused. So
    is a NetCDF file written before the ArviZ groups (:func:`phase_format` below
    :data:`~bubblecal.inference.idata.IDATA_FORMAT`), with a one-line notice.

    ``exports[name]`` (:class:`~bubblecal.inference.idata.ExportInfo`) names the dimensions, units and constant
    data of a phase's file; ``pointwise_fns[name](result)`` gives the pointwise log likelihood of a phase whose
    model has no observed site (phase 2); :attr:`pointwise` holds each phase's pointwise log likelihood.

    With ``background``, :meth:`save` traces the model on the caller's thread and leaves building the
    InferenceData and writing the file to a :class:`~bubblecal.workflows.calibrate.writer.PhaseWriter` (one
    thread, or ``writers`` processes), so the next phase samples meanwhile; :meth:`flush` waits for every write
    (call it before reading the files, and in a ``finally`` so that a failing run still leaves its finished
    phases on disk). A phase enters the manifest only once its file is complete, as without ``background``.
    """

    def __init__(self, folder: Path, netcdf: bool = True, force: bool = False, run_info: Mapping | None = None,
                 say: Callable[[str], None] | None = None, background: bool = False, writers: int | None = None):
        self.folder = Path(folder)
        self.netcdf = netcdf
        self.force = force
        self.say = say or (lambda _m: None)
        self.expected: dict[str, str] = {}
        self.loglik: dict[str, np.ndarray] = {}
        self.exports: dict = {}
        self.pointwise_fns: dict[str, Callable] = {}
        self.pointwise: dict[str, dict[str, np.ndarray]] = {}
        self.reused: list[str] = []
        self.recomputed: list[str] = []
        self.manifest_path = self.folder / "manifest.json"
        self.manifest = self._read_manifest()
        if run_info is not None:
            self.manifest["run"] = dict(run_info)
        self.background = background
        self.writers = writers
        self._writer = None

    def start_writers(self) -> None:
        """Start the background writers now (their process start and imports overlap the work before the first
        phase ends); :meth:`save` starts them otherwise. Nothing for a store without ``background``."""
        if not self.background or self._writer is not None:
            return
        from bubblecal.workflows.calibrate.writer import PhaseWriter

        self._writer = PhaseWriter(self.writers)
        if self.netcdf:
            self._writer.start()

    def _read_manifest(self) -> dict:
        """The folder's manifest, or an empty one when absent or unreadable."""
        if self.manifest_path.is_file():
            try:
                manifest = json.loads(self.manifest_path.read_text(encoding="utf-8"))
            except (json.JSONDecodeError, UnicodeDecodeError, OSError):
                manifest = None  # a damaged manifest reuses nothing: every phase runs and it is rewritten
            if isinstance(manifest, dict) and isinstance(manifest.get("phases"), dict):
                return manifest
        return {"format": "bubblecal-calibration-run", "format_version": 1, "phases": {}}

    def write_manifest(self) -> None:
        """Write ``manifest.json`` atomically."""
        text = json.dumps(self.manifest, indent=1, default=str, allow_nan=True)
        atomic_write(self.manifest_path, lambda p: p.write_text(text))

    def close_soon(self) -> None:
        """No more phases will be saved: the writer processes end once the queued files are written (:meth:`flush`
        still waits for them and enters them in the manifest)."""
        if self._writer is not None:
            self._writer.close_soon()

    def flush(self) -> None:
        """Wait for the phase files :meth:`save` left to the writer, and enter them in the manifest.

        Raises
        ------
        Exception
            The first error a background write raised (every other write still finishes first).
        """
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.close()

    def path(self, name: str) -> Path:
        """The file that :meth:`save` writes for phase ``name``."""
        return self.folder / (f"{name}.nc" if self.netcdf else f"{name}.npz")

    def _existing(self, name: str) -> Path | None:
        """The stored file of phase ``name`` (either suffix), or None."""
        for suffix in (".nc", ".npz"):
            p = self.folder / f"{name}{suffix}"
            if p.is_file():
                return p
        return None

    def load(self, name: str):
        """The stored result of phase ``name`` when its file exists and its hash matches ``expected``.

        Parameters
        ----------
        name : str
            Phase name, e.g. 'phase2'.

        Returns
        -------
        bubblecal.inference.phase_results.PhaseResult or None
            None when the phase must run (also with ``force``, when its file is damaged or when a phase it
            depends on runs; its name then goes to :attr:`recomputed`); else the result, its log likelihoods
            recorded in :attr:`loglik` and its name in :attr:`reused`.
        """
        entry = self.manifest["phases"].get(name)
        path = self._existing(name)
        if self.force or entry is None or path is None or entry.get("config_hash") != self.expected.get(name):
            self.recomputed.append(name)
            return None
        upstream = [r for r in self.recomputed if any(fnmatch.fnmatchcase(r, p) for p in phase_dependencies(name))]
        if upstream:
            self.say(f"{name}: recomputed, it depends on {', '.join(upstream)}")
            self.recomputed.append(name)
            return None
        try:
            result, loglik = read_phase(path)
            legacy = path.suffix == ".nc" and phase_format(path) < IDATA_FORMAT
            pointwise = {} if legacy else read_pointwise(path)
        except PhaseFileError as exc:
            self.say(f"{exc}; recomputing {name} and the phases that depend on it")
            self.recomputed.append(name)
            return None
        if legacy:
            self.say(f"{path}: written before the ArviZ groups (log_likelihood, observed_data, constant_data); "
                     f"recomputing {name} and the phases that depend on it")
            self.recomputed.append(name)
            return None
        self.loglik[name] = loglik
        self.pointwise[name] = pointwise
        self.reused.append(name)
        return result

    def save(self, result) -> None:
        """Write a finished phase atomically and record it (hash, log Z, status, seconds) in the manifest.

        Parameters
        ----------
        result : bubblecal.inference.phase_results.PhaseResult
            The phase; its sampler's final log likelihoods are stored with the draws.
        """
        name = result.name
        path = self.path(name)
        loglik = np.asarray(result.sampler.state.log_likelihood) if result.sampler is not None else None
        if loglik is not None:
            self.loglik[name] = loglik
        attrs = {"config_hash": self.expected.get(name, ""), "phase": name, "phase_result_chains": "first"}
        fn = self.pointwise_fns.get(name)
        pointwise = fn(result) if fn is not None else None
        if pointwise is not None:
            self.pointwise[name] = {k: np.asarray(v) for k, v in pointwise.items()}
        from bubblecal.workflows.calibrate.phase_files import phase_inference_parts, write_phase

        info = self.exports.get(name)
        entry = {"file": path.name, "config_hash": self.expected.get(name, ""), "log_evidence": result.log_evidence,
                 "log_evidence_se": result.log_evidence_se if math.isfinite(result.log_evidence_se) else None,
                 "status": result.status, "seconds": result.seconds,
                 "num_draws": int(next(iter(result.samples.values())).shape[0])}
        if not self.background:
            write_phase(path, result, loglik, attrs, info=info, pointwise=pointwise)
            self._record(name, entry)
            return
        parts = phase_inference_parts(result, loglik, info=info, pointwise=pointwise) if self.netcdf else None
        self.start_writers()
        self._writer.submit(lambda: self._record(name, entry), path, result, loglik, attrs, info=info,
                            pointwise=pointwise, parts=parts)

    def _record(self, name: str, entry: Mapping) -> None:
        """Enter a written phase in the manifest and write it (on the caller's thread, also for background writes)."""
        self.manifest["phases"][name] = dict(entry)
        self.write_manifest()


def phase_dependencies(name: str) -> tuple[str, ...]:
    """The phases whose draws phase ``name`` is computed from, as :func:`fnmatch.fnmatchcase` name patterns.

    Parameters
    ----------
    name : str
        ``phase1_<dataset>``, ``phase2``, ``phase3_<dataset>`` or ``joint_nuts``.

    Returns
    -------
    tuple of str
        Phase 1 and the joint run: none; phase 2: every phase 1 (``phase1_*``); phase 3 of a dataset: its
        phase 1 and phase 2.
    """
    if name == "phase2":
        return ("phase1_*",)
    if name.startswith("phase3_"):
        return ("phase1_" + name.removeprefix("phase3_"), "phase2")
    return ()
