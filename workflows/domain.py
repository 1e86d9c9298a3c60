"""Does a prior box stay inside a surrogate's training box? (``bubblecal compare`` and ``calibrate``)."""

from __future__ import annotations

import itertools
import warnings

import numpy as np

from bubblecal.data import SHELL_PARAMETERS

__all__ = ["PRIOR_BOX_RTOL", "prior_box_domain_warnings"]

#: Slack of the prior-box check, as a fraction of each training range: a Latin hypercube of n points samples the
#: edge strata only to within width/n of the box edge, and the reduced shell's b1 = b2 = a4 = 0 sits on it.
PRIOR_BOX_RTOL = 0.01


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
