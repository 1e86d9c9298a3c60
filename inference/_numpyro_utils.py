"""Turn a NumPyro model into flat log-prior / log-likelihood functions for the TMCMC core.

The split is by site type, from a trace of the model with the latent values substituted:

- prior = Σ log p(latent sample sites) (+ log|J| of the bijection to unconstrained space, computed
  here from ``biject_to(support)``; NumPyro's own ``_<name>_log_det`` factor sites are never created
  because the model is run with constrained values substituted, not through NumPyro's reparam);
- likelihood = Σ log p(observed sample sites), which includes every user ``numpyro.factor`` site
  (a factor is an observed ``Unit`` site).

Site ``scale`` (plates with subsampling, ``numpyro.handlers.scale``) and masks are honoured as in
``numpyro.infer.util.log_density``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jax.flatten_util import ravel_pytree
from numpyro import handlers
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to
from numpyro.distributions.util import is_identically_one, sum_rightmost
from numpyro.infer import Predictive

# Uniform draws can land exactly on a bound in float32; the bijection then maps them to ±inf.
# Such (rare) draws are moved to this finite unconstrained value (a point within ~1e-9 of the bound).
_UNCONSTRAINED_CLIP = 20.0


def _site_log_prob(site) -> jax.Array:
    value = site["value"]
    if site["intermediates"]:
        log_prob = site["fn"].log_prob(value, site["intermediates"])
    else:
        log_prob = site["fn"].log_prob(value)
    scale = site["scale"]
    if scale is not None and not is_identically_one(scale):
        log_prob = scale * log_prob
    return jnp.sum(log_prob)


def _elementwise(support):
    """Strip ``independent`` wrappers: the constraint that acts on single elements."""
    while isinstance(support, constraints.independent):
        support = support.base_constraint
    return support


def _model_label(model) -> str:
    return getattr(model, "__qualname__", None) or getattr(model, "__name__", None) or repr(model)


class FlatModel:
    """A NumPyro model bound to its arguments, seen through one flat parameter vector.

    ``space='unconstrained'`` (default): the vector is the unconstrained image of the latent sites and
    the prior includes log|J|.  ``space='constrained'``: the vector holds the constrained values
    themselves (Korali's behaviour on box priors); the prior is −∞ outside each site's support.
    """

    def __init__(
        self, model: Callable, model_args=(), model_kwargs=None, space="unconstrained", rng_key=None
    ):
        if space not in ("unconstrained", "constrained"):
            raise ValueError(f"space must be 'unconstrained' or 'constrained', got {space!r}")
        self.model = model
        self.label = _model_label(model)
        self.args = tuple(model_args)
        self.kwargs = dict(model_kwargs or {})
        self.space = space
        rng_key = jax.random.PRNGKey(0) if rng_key is None else rng_key
        proto = handlers.trace(handlers.seed(model, rng_key)).get_trace(*self.args, **self.kwargs)
        self.latent: list[str] = []
        self.transforms = {}
        self.scales = {}
        self.event_dims = {}
        self.deterministic: list[str] = []
        for name, site in proto.items():
            if site["type"] == "deterministic":
                self.deterministic.append(name)
            if site["type"] != "sample" or site["is_observed"]:
                continue
            if site["infer"].get("is_auxiliary"):
                continue
            fn = site["fn"]
            if fn.support.is_discrete:
                raise ValueError(
                    f"model {self.label!r}: latent site {name!r} is discrete; TMCMC needs continuous latents"
                )
            if space == "constrained" and _elementwise(fn.support).event_dim != 0:
                raise ValueError(
                    f"model {self.label!r}: site {name!r} has support {fn.support} with event_dim > 0; "
                    "space='constrained' needs elementwise (box-like) supports, use space='unconstrained'"
                )
            self.latent.append(name)
            self.transforms[name] = biject_to(fn.support)
            self.scales[name] = site["scale"]
            self.event_dims[name] = len(fn.event_shape)
        if not self.latent:
            raise ValueError(f"model {self.label!r} has no continuous latent sample sites")
        proto_values = {k: proto[k]["value"] for k in self.latent}
        flat0, self._unravel = ravel_pytree(self._to_flat_space(proto_values))
        self.dim = int(flat0.shape[0])
        self.dtype = flat0.dtype

    # -- spaces -------------------------------------------------------------------------------

    def _to_flat_space(self, constrained: dict) -> dict:
        if self.space == "constrained":
            return dict(constrained)
        out = {}
        for k, v in constrained.items():
            u = self.transforms[k].inv(v)
            out[k] = jnp.where(jnp.isfinite(u), u, jnp.sign(u) * _UNCONSTRAINED_CLIP)
        return out

    def constrain(self, x: jax.Array) -> dict:
        params = self._unravel(x)
        if self.space == "constrained":
            return params
        return {k: self.transforms[k](v) for k, v in params.items()}

    def flatten(self, constrained: dict) -> jax.Array:
        return ravel_pytree(self._to_flat_space({k: constrained[k] for k in self.latent}))[0]

    # -- densities ----------------------------------------------------------------------------

    def _trace(self, values: dict):
        model = handlers.substitute(handlers.seed(self.model, jax.random.PRNGKey(0)), data=values)
        return handlers.trace(model).get_trace(*self.args, **self.kwargs)

    def log_terms(self, x: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(log prior in the flat space, log likelihood) of one flat vector."""
        params = self._unravel(x)
        if self.space == "constrained":
            values = params
            log_jac = jnp.zeros((), self.dtype)
        else:
            values = {}
            log_jac = jnp.zeros((), self.dtype)
            for k, u in params.items():
                t = self.transforms[k]
                v = t(u)
                values[k] = v
                ld = t.log_abs_det_jacobian(u, v)
                ld = sum_rightmost(ld, jnp.ndim(ld) - jnp.ndim(v) + self.event_dims[k])
                scale = self.scales[k]
                if scale is not None and not is_identically_one(scale):
                    ld = scale * ld
                log_jac = log_jac + jnp.sum(ld)
        tr = self._trace(values)
        log_prior = log_jac
        log_lik = jnp.zeros((), self.dtype)
        for name, site in tr.items():
            if site["type"] != "sample":
                continue
            lp = _site_log_prob(site)
            if site["is_observed"]:
                log_lik = log_lik + lp
            elif name in self.transforms:
                if self.space == "constrained":
                    inside = jnp.all(site["fn"].support(site["value"]))
                    lp = jnp.where(inside, lp, -jnp.inf)
                log_prior = log_prior + lp
        return log_prior, log_lik

    def log_prior(self, x):
        return self.log_terms(x)[0]

    def log_likelihood(self, x):
        return self.log_terms(x)[1]

    def sites(self, x: jax.Array) -> dict:
        """Constrained latent values and deterministic sites of one flat vector."""
        values = self.constrain(x)
        out = dict(values)
        if self.deterministic:
            tr = self._trace(values)
            for name in self.deterministic:
                out[name] = tr[name]["value"]
        return out

    # -- prior draws --------------------------------------------------------------------------

    def prior_draws(self, rng_key, num: int) -> jax.Array:
        """Exact prior draws (NumPyro ``Predictive``), mapped to the flat space: shape (num, dim)."""
        pred = Predictive(self.model, num_samples=num, return_sites=self.latent, parallel=True)
        draws = pred(rng_key, *self.args, **self.kwargs)
        return jax.vmap(self.flatten)(draws)
