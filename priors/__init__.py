"""bubblecal.priors: user-editable prior/hyperprior TOML files (one per workflow) and their loader."""

from bubblecal.priors.spec import (
    Bounds,
    NoisePrior,
    ParameterPrior,
    PriorError,
    PriorSpec,
    available_priors,
    check_priors,
    load_priors,
    prior_path,
    workflow_file_name,
)

__all__ = [
    "Bounds", "ParameterPrior", "NoisePrior",
    "PriorSpec", "PriorError", "available_priors", "check_priors", "load_priors", "prior_path",
    "workflow_file_name",
]
