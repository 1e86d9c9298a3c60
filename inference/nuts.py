"""NUTS cross-check runner: NumPyro NUTS over several chains with r_hat / bulk ESS per parameter.

Progress is drawn with rich (``progress=True``: the warm-up and sampling phases on one line), not with
NumPyro's own bar: with it on, the run is ``MCMC.warmup`` then ``MCMC.run`` from the warmed-up state and its
key, which continues the same chains, so a seed gives the same draws with progress on or off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import jax
import numpy as np
from numpyro.diagnostics import summary
from numpyro.infer import MCMC, NUTS, init_to_uniform

from bubblecal._progress import ProgressLine


@dataclass
class NUTSResult:
    """Samples of a NUTS run and its convergence diagnostics.

    Parameters
    ----------
    samples : dict of str to numpy.ndarray
        Site name -> (num_chains * num_samples, ...) draws, chains concatenated.
    samples_by_chain : dict of str to numpy.ndarray
        The same with a leading chain axis.
    summary : dict
        NumPyro's per-site summary (mean, std, median, quantiles, n_eff, r_hat).
    max_r_hat, min_n_eff : float
        Largest r_hat and smallest bulk ESS over every component.
    num_divergences : int
        Divergent transitions after warm-up.
    mcmc : numpyro.infer.MCMC
        The NumPyro MCMC object.
    diverging : numpy.ndarray or None
        (chain, draw) divergence flags.
    potential_energy : numpy.ndarray or None
        (chain, draw) potential energy (−log density of the unconstrained model).
    model_call : tuple or None
        (model, args, kwargs) of the run (for the pointwise log likelihood of the export).
    """

    samples: dict
    samples_by_chain: dict
    summary: dict
    max_r_hat: float
    min_n_eff: float
    num_divergences: int
    mcmc: MCMC = field(repr=False)
    diverging: np.ndarray | None = field(default=None, repr=False)
    potential_energy: np.ndarray | None = field(default=None, repr=False)
    model_call: tuple | None = field(default=None, repr=False)

    def to_inference_data(self, info=None, log_likelihood=True, chunk_size: int = 1024):
        """The chains as ArviZ InferenceData.

        Parameters
        ----------
        info : bubblecal.inference.idata.ExportInfo or None
            Dimension names, coordinates, units, constant data and attributes from the caller.
        log_likelihood : bool or mapping of str to array_like
            True: the pointwise log likelihood and observed values of the model's observed sites; a mapping:
            those (chain, draw, ...) arrays instead; False: none.
        chunk_size : int
            Draws per vectorised evaluation of the pointwise log likelihood.

        Returns
        -------
        arviz.InferenceData
            posterior (chain, draw, ...); sample_stats 'lp' (−potential energy) and 'diverging' per draw;
            log_likelihood and observed_data; r_hat, ESS and divergences in the attrs.
        """
        from bubblecal.inference.idata import _likelihood_groups, build_inference_data

        stats = {}
        if self.potential_energy is not None:
            stats["lp"] = -np.asarray(self.potential_energy)
        if self.diverging is not None:
            stats["diverging"] = np.asarray(self.diverging, dtype=bool)
        model, args, kwargs = self.model_call or (None, (), None)
        pointwise, observed = _likelihood_groups(model, self.samples_by_chain, args, kwargs, log_likelihood, info,
                                                 chunk_size)
        attrs = {"inference_library": "numpyro.infer.NUTS", "max_r_hat": self.max_r_hat,
                 "min_n_eff": self.min_n_eff, "num_divergences": self.num_divergences}
        return build_inference_data(self.samples_by_chain, sample_stats=stats or None, log_likelihood=pointwise,
                                    observed_data=observed, info=info, attrs=attrs)

    def get_samples(self) -> dict:
        """The chains-concatenated samples (as ``MCMC.get_samples``)."""
        return self.samples

    @property
    def converged(self) -> bool:
        """r_hat ≤ 1.01 and bulk ESS ≥ 400 for every component, no divergences."""
        return self.max_r_hat <= 1.01 and self.min_n_eff >= 400 and self.num_divergences == 0

    def convergence_note(self) -> str | None:
        """Why the run does not count as :attr:`converged`, in one sentence, or None when it does."""
        if self.converged:
            return None
        return (f"NUTS did not converge (max r_hat {self.max_r_hat:.3g}, min bulk ESS {self.min_n_eff:.0f}, "
                f"{self.num_divergences} divergences; wanted r_hat <= 1.01, ESS >= 400, none): the posterior is "
                "not reliable")


def run_nuts(
    model: Callable,
    *args,
    rng_key=None,
    num_warmup: int = 1000,
    num_samples: int = 1000,
    num_chains: int = 4,
    chain_method: str = "vectorized",
    target_accept_prob: float = 0.8,
    dense_mass: bool = False,
    max_tree_depth: int = 10,
    progress: bool = False,
    init_strategy: Callable | None = None,
    **kwargs,
) -> NUTSResult:
    """Run NumPyro NUTS on ``model(*args, **kwargs)`` with ``num_chains`` chains.

    Parameters
    ----------
    model : callable
        NumPyro model.
    *args, **kwargs
        Arguments of the model.
    rng_key : jax.Array or None
        PRNG key (default ``PRNGKey(0)``).
    num_warmup, num_samples, num_chains : int
        Warm-up and kept draws per chain, and the number of chains.
    chain_method : str
        Passed to ``numpyro.infer.MCMC`` ('vectorized' works on one device; 'parallel' needs one device
        per chain).
    target_accept_prob : float
        NUTS target acceptance.
    dense_mass : bool
        Dense mass matrix adaptation.
    max_tree_depth : int
        NUTS maximum tree depth.
    progress : bool
        Show the warm-up and sampling phases (a rich line); the draws do not depend on it, but the two phases
        are compiled separately (one compilation more than without it).
    init_strategy : callable or None
        A NumPyro init strategy (default ``init_to_uniform``), e.g. ``init_to_value(values=...)`` to
        start chains away from a flat region of the likelihood.

    Returns
    -------
    NUTSResult
        Samples (deterministic sites included) and diagnostics.

    Raises
    ------
    ValueError
        If a draw count is not an integer of the allowed range.
    """
    for name, value, minimum in (
        ("num_warmup", num_warmup, 0),
        ("num_samples", num_samples, 1),
        ("num_chains", num_chains, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    rng_key = jax.random.PRNGKey(0) if rng_key is None else rng_key
    kernel = NUTS(
        model, target_accept_prob=target_accept_prob, dense_mass=dense_mass, max_tree_depth=max_tree_depth,
        init_strategy=init_to_uniform if init_strategy is None else init_strategy,
    )
    mcmc = MCMC(
        kernel,
        num_warmup=num_warmup,
        num_samples=num_samples,
        num_chains=num_chains,
        chain_method=chain_method,
        progress_bar=False,
    )
    if progress and num_warmup > 0:
        with ProgressLine(f"NUTS {num_chains} chain(s)", total=2) as line:
            line.update(info=f"warm-up: {num_warmup} steps per chain")
            mcmc.warmup(rng_key, *args, **kwargs)
            line.update(advance=1, info=f"sampling: {num_samples} draws per chain")
            # the warmed-up state carries the chains' keys: running from them continues the same chains
            mcmc.run(mcmc.post_warmup_state.rng_key, *args, extra_fields=("diverging", "potential_energy"), **kwargs)
            line.update(advance=1)
    else:
        with ProgressLine(f"NUTS {num_chains} chain(s)", total=1, enabled=progress) as line:
            line.update(info=f"sampling: {num_samples} draws per chain")
            mcmc.run(rng_key, *args, extra_fields=("diverging", "potential_energy"), **kwargs)
            line.update(advance=1)
    by_chain = {k: np.asarray(v) for k, v in mcmc.get_samples(group_by_chain=True).items()}
    flat = {k: v.reshape((-1,) + v.shape[2:]) for k, v in by_chain.items()}
    summ = summary(by_chain, group_by_chain=True)
    r_hats = [np.max(np.nan_to_num(np.asarray(s["r_hat"]), nan=1.0)) for s in summ.values()]
    n_effs = [np.min(np.asarray(s["n_eff"])) for s in summ.values()]
    extra = mcmc.get_extra_fields(group_by_chain=True)
    div = int(np.asarray(extra["diverging"]).sum())
    return NUTSResult(
        samples=flat,
        samples_by_chain=by_chain,
        summary=summ,
        max_r_hat=float(np.max(r_hats)),
        min_n_eff=float(np.min(n_effs)),
        num_divergences=div,
        mcmc=mcmc,
        diverging=np.asarray(extra["diverging"]),
        potential_energy=np.asarray(extra["potential_energy"]),
        model_call=(model, args, kwargs),
    )
