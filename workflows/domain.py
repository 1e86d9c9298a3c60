"""Does a prior box stay inside a surrogate's training box? (``bubblecal compare`` and ``calibrate``)."""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from bubblecal.data import SHELL_PARAMETERS

__all__ = ["PRIOR_BOX_RTOL", "TIER_VALIDATED_DIAMETERS_UM", "prior_box_domain_warnings", "acoustic_ka_domain_warnings",
           "tier_validation_warnings"]

#: Slack of the prior-box check, as a fraction of each training range: a Latin hypercube of n points samples the
#: edge strata only to within width/n of the box edge, and the reduced shell's b1 = b2 = a4 = 0 sits on it.
PRIOR_BOX_RTOL = 0.01

#: Diameters [um] per protocol between which the quasi-static training curves agree with the explicit tier within
#: the 3 % gate (benchmarks/RESULTS.md, "Fidelity tiers" and "Training sets over the diameter"): compression fails at
#: 4.5 um, where shells buckle under the plates; indentation at 7.0 um.
TIER_VALIDATED_DIAMETERS_UM = {"compression": (1.8, 3.0), "indentation": (1.8, 5.8)}


def prior_box_domain_warnings(surrogate, spec, x) -> list[str]:
    """Messages of ``surrogate.check_domain`` over the corners of the prior box.

    A corner counts as outside only beyond :data:`PRIOR_BOX_RTOL` of the training range. Compression
    evaluates the surrogate at max(0, x − d0) for d0 at both ends of its prior; indentation at x.

    Parameters
    ----------
    surrogate : bubblecal.surrogates.Surrogate
        A mechanical surrogate (anything with ``check_domain(params, x, rtol=)``).
    spec : bubblecal.priors.PriorSpec
        The priors whose box (free parameters) and fixed values are checked.
    x : array_like
        The curve's loading coordinate (DPD length for compression, DPD force for indentation).

    Returns
    -------
    list of str
        One message per :class:`bubblecal.surrogates.SurrogateDomainWarning` raised; empty when the box fits.
    """
    from bubblecal.surrogates import SurrogateDomainWarning

    axes = [spec.parameters[k].prior.as_tuple() if k in spec.parameters else (spec.fixed[k],)
            for k in SHELL_PARAMETERS]
    corners = np.array(list(itertools.product(*axes)), dtype=float)
    x = np.asarray(x, dtype=float)
    if spec.setup == "compression":
        d0s = spec.parameters["d0"].prior.as_tuple() if "d0" in spec.parameters else (spec.fixed["d0"],)
        xs = np.concatenate([np.maximum(0.0, x - d0) for d0 in d0s])
    else:
        xs = x
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SurrogateDomainWarning)
        surrogate.check_domain(corners[:, None, :], xs[None, :], rtol=PRIOR_BOX_RTOL)
    return [str(w.message) for w in caught if issubclass(w.category, SurrogateDomainWarning)]


def acoustic_ka_domain_warnings(f_res, spec, datasets, label: str) -> list[str]:
    """Messages for every acoustic diameter whose fitted k_a range does not contain the k_a prior.

    Parameters
    ----------
    f_res : bubblecal.surrogates.AcousticSurrogate
        The acoustic surrogate (per-diameter quadratics or the law over the diameter).
    spec : bubblecal.priors.PriorSpec
        The priors (their ``ka`` range, DPD units).
    datasets : sequence
        Acoustic datasets (their ``diameter_um`` [um]).
    label : str
        The agent named in the messages.

    Returns
    -------
    list of str
        One message per diameter outside; empty when every fitted range holds the prior.

    Raises
    ------
    bubblecal.surrogates.acoustic.AcousticRangeError
        When ``f_res`` has no fit at a diameter.
    """
    lo, hi = spec.parameters["ka"].prior.as_tuple()
    out = []
    for ds in datasets:
        for d in np.atleast_1d(ds.diameter_um):
            r_lo, r_hi = f_res.ka_ranges(float(d))
            if lo < r_lo * (1 - 1e-9) or hi > r_hi * (1 + 1e-9):
                out.append(f"acoustic {label} {float(d):g} um: fitted ka range [{r_lo:.6g}, {r_hi:.6g}] "
                           f"does not contain the ka prior [{lo:.6g}, {hi:.6g}]")
    return out


def tier_validation_warnings(protocol: str, diameter_um: float, name: str) -> list[str]:
    """A note for a bubble whose size lies outside :data:`TIER_VALIDATED_DIAMETERS_UM` of its protocol.

    Parameters
    ----------
    protocol : {'compression', 'indentation'}
        The bubble's loading protocol.
    diameter_um : float
        Its diameter [um].
    name : str
        The bubble's name in the message.

    Returns
    -------
    list of str
        One message, or none inside the validated range.
    """
    lo, hi = TIER_VALIDATED_DIAMETERS_UM[protocol]
    if lo <= diameter_um <= hi:
        return []
    why = (" (larger shells buckle under the plates in the quasi-static tier, not in the explicit one within its "
           "protocol: docs/physics.md, 'Buckling under the plates')" if protocol == "compression" and diameter_um > hi
           else "")
    return [f"{name}: {protocol} at {diameter_um:g} um is outside {lo:g}-{hi:g} um, where the training curves of "
            f"the networks over the diameter were checked against the explicit tier{why}; read its fit with that "
            "in mind"]
