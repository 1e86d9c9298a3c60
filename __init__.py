"""bubblecal: DPD microbubble shell models calibrated against AFM and acoustic data.

Subpackages (layers point one way, ARCHITECTURE.md: workflows -> every layer; campaigns -> sim, priors, data;
models -> surrogates, priors, data; surrogates, priors, sim -> data; inference knows no physics):

- ``bubblecal.data``        units, reference curves, acoustic observations, loaders
- ``bubblecal.priors``      prior/hyperprior TOML files and their typed loader
- ``bubblecal.sim``         Warp DPD simulator
- ``bubblecal.campaigns``   training-data campaigns: campaign files, designs, Dask runner, store status
- ``bubblecal.surrogates``  MLP / acoustic surrogates (train in torch, evaluate in JAX)
- ``bubblecal.models``      NumPyro models
- ``bubblecal.inference``   TMCMC, NUTS, hierarchy, predictive metrics, sensitivity
- ``bubblecal.workflows``   the ``bubblecal`` command line and pipelines

The lean install calibrates; simulation, training and the rest come with extras (README, "Install"): using a part
whose extra is missing raises :class:`MissingExtraError`, which names the extra to install.
"""

from importlib.metadata import PackageNotFoundError, version

from bubblecal._extras import MissingExtraError

try:
    __version__ = version("bubblecal")
except PackageNotFoundError:  # running from a source tree that was never installed
    __version__ = "0.0.0+unknown"

__all__ = ["__version__", "MissingExtraError"]
