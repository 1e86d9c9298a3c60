"""bubblecal.priors: the user-edited prior/hyperprior TOML files (one per workflow) and their typed loader.

Every public object of the layer is imported from here, e.g.::

    from bubblecal.priors import PriorError, load_priors

* the specification types (:mod:`~bubblecal.priors.spec`): :class:`PriorSpec`, :class:`ParameterPrior`,
  :class:`NoisePrior`, :class:`Bounds`;
* finding, loading and checking files (:mod:`~bubblecal.priors.loading`), validated by
  :mod:`~bubblecal.priors.validation`;
* an editable template for a user's agent (:mod:`~bubblecal.priors.template`).
"""

from bubblecal.priors.loading import (
    PriorError,
    available_priors,
    check_priors,
    load_priors,
    prior_path,
    workflow_file_name,
)
from bubblecal.priors.spec import Bounds, NoisePrior, ParameterPrior, PriorSpec
from bubblecal.priors.template import priors_template

__all__ = [
    "Bounds", "ParameterPrior", "NoisePrior",
    "PriorSpec", "PriorError", "available_priors", "check_priors", "load_priors", "prior_path",
    "workflow_file_name", "priors_template",
]
