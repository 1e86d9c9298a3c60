"""Posterior agreement between two samplers (e.g. TMCMC vs NUTS).

For every scalar component of every site present in both sample sets:

- quantile differences at 5/25/50/75/95 % in units of the pooled posterior sd
  (sd = mean of the two samples' sds);
- the two-sample Kolmogorov–Smirnov statistic.

Verdict (defaults, stated in the result): a component passes when every central quantile
(25/50/75 %) differs by ≤ ``max_central_diff`` = 0.2 sd, each tail quantile (5/95 %) by
≤ ``max_tail_diff`` = 0.3 sd, and the KS statistic is ≤ ``max_ks`` = 0.1 (about three times the
sampling noise of ~1,000 effective draws per side; the reasoning is in ``docs/decisions.md``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.stats import ks_2samp

if TYPE_CHECKING:
    from bubblecal.inference.phase_results import StagedResult

QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)


@dataclass
class Comparison:
    """Result of :func:`compare_posteriors`.

    Parameters
    ----------
    table : list of dict
        One row per scalar component: name, sd, dq_05 .. dq_95 (quantile differences in units of the
        pooled sd), ks, passed.
    passed : bool
        Every component passed.
    thresholds : dict
        The thresholds used.
    """

    table: list
    passed: bool
    thresholds: dict

    def __str__(self) -> str:
        """The table as text, with the verdict."""
        head = f"{'parameter':>16s} " + " ".join(f"dq{int(q * 100):02d}".rjust(7) for q in QUANTILES)
        lines = [head + "      KS  pass"]
        for row in self.table:
            dq = " ".join(f"{row[f'dq_{int(q * 100):02d}']:7.3f}" for q in QUANTILES)
            lines.append(f"{row['name']:>16s} {dq} {row['ks']:7.3f}  {'yes' if row['passed'] else 'NO'}")
        th = self.thresholds
        lines.append(
            f"verdict: {'PASS' if self.passed else 'FAIL'} (central |dq| <= {th['max_central_diff']} sd, "
            f"tail |dq| <= {th['max_tail_diff']} sd, KS <= {th['max_ks']})"
        )
        return "\n".join(lines)


def _as_samples(obj) -> dict:
    """Dict of NumPy arrays from a dict of samples or an object with ``get_samples()``."""
    if isinstance(obj, dict):
        return {k: np.asarray(v) for k, v in obj.items()}
    if hasattr(obj, "get_samples"):
        return {k: np.asarray(v) for k, v in obj.get_samples().items()}
    raise ValueError(f"expected a dict of samples or an object with get_samples(), got {type(obj).__name__}")


def _components(samples: dict, names) -> dict:
    """Scalar components ``name[i,j]`` of the named sites."""
    out = {}
    for name in names:
        v = samples[name]
        if v.ndim == 1:
            out[name] = v
        else:
            flat = v.reshape(v.shape[0], -1)
            for j in range(flat.shape[1]):
                idx = np.unravel_index(j, v.shape[1:])
                out[f"{name}[{','.join(map(str, idx))}]"] = flat[:, j]
    return out


def compare_posteriors(
    a,
    b,
    *,
    names=None,
    max_central_diff: float = 0.2,
    max_tail_diff: float = 0.3,
    max_ks: float = 0.1,
) -> Comparison:
    """Compare two posterior sample sets component by component (module docstring for the verdict).

    Parameters
    ----------
    a, b : dict or object
        Sample sets: dicts name -> (draws, ...) or objects with ``get_samples()``.
    names : sequence of str or None
        Sites to compare (default every site present in both).
    max_central_diff, max_tail_diff : float
        Largest allowed |quantile difference| (pooled sd units) at the central and the tail quantiles.
    max_ks : float
        Largest allowed two-sample KS statistic.

    Returns
    -------
    Comparison

    Raises
    ------
    ValueError
        For sites missing from a set, no common site, or fewer than 2 draws on a side.
    """
    sa, sb = _as_samples(a), _as_samples(b)
    common = [k for k in sa if k in sb] if names is None else list(names)
    missing = [k for k in common if k not in sa or k not in sb]
    if missing:
        raise ValueError(f"sites {missing} are not in both sample sets")
    if not common:
        raise ValueError("the two sample sets share no site names")
    ca, cb = _components(sa, common), _components(sb, common)
    rows = []
    for name in ca:
        xa, xb = ca[name].astype(float), cb[name].astype(float)
        if len(xa) < 2 or len(xb) < 2:
            raise ValueError(f"{name}: need at least 2 draws on each side")
        sd = 0.5 * (xa.std(ddof=1) + xb.std(ddof=1))
        sd = sd if sd > 0 else 1.0
        qa, qb = np.quantile(xa, QUANTILES), np.quantile(xb, QUANTILES)
        dq = (qa - qb) / sd
        ks = float(ks_2samp(xa, xb).statistic)
        central = np.abs(dq[1:4]).max() <= max_central_diff
        tails = max(abs(dq[0]), abs(dq[4])) <= max_tail_diff
        row = {"name": name, "sd": float(sd), "ks": ks}
        row.update({f"dq_{int(q * 100):02d}": float(v) for q, v in zip(QUANTILES, dq, strict=True)})
        row["passed"] = bool(central and tails and ks <= max_ks)
        rows.append(row)
    return Comparison(
        table=rows,
        passed=all(r["passed"] for r in rows),
        thresholds={"max_central_diff": max_central_diff, "max_tail_diff": max_tail_diff, "max_ks": max_ks},
    )


def compare_staged_joint(staged: StagedResult, joint_samples: Mapping[str, np.ndarray],
                         dataset_sites: Mapping[str, Mapping[str, tuple[str, int | None]]] | None = None):
    """Compare staged and joint marginals: ψ (m_*, tau_*) and each dataset's Θ_i.

    Parameters
    ----------
    staged : StagedResult
        The staged run.
    joint_samples : mapping of str to array_like
        Samples of the joint model.
    dataset_sites : mapping or None
        ``dataset_sites[name]`` maps a phase-3 site (e.g. 'ka') to the joint model's (site, index)
        holding that dataset's value (e.g. ('ka', 2) for the third curve of a plate; index None for a
        site of its own).

    Returns
    -------
    dict
        ``{'psi': Comparison, name: Comparison, ...}`` from :func:`compare_posteriors`.
    """
    out = {}
    psi_staged = staged.psi_samples
    psi_joint = {k: np.asarray(joint_samples[k]) for k in psi_staged if k in joint_samples}
    if psi_joint:
        out["psi"] = compare_posteriors({k: psi_staged[k] for k in psi_joint}, psi_joint)
    for result in staged.phase3:
        name = result.name.removeprefix("phase3_")
        mapping = (dataset_sites or {}).get(name)
        if not mapping:
            continue
        a, b = {}, {}
        for site, (joint_site, index) in mapping.items():
            if site in result.samples and joint_site in joint_samples:
                a[site] = np.asarray(result.samples[site])
                joint = np.asarray(joint_samples[joint_site])
                b[site] = joint if index is None else joint[..., index]
        if a:
            out[name] = compare_posteriors(a, b)
    return out
