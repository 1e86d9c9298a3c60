"""Turn a NumPyro model into flat log-prior / log-likelihood functions for the TMCMC core.

The split is by site type, from a trace of the model with the latent values substituted:

- prior = Σ log p(latent sample sites) (+ log|J| of the bijection to unconstrained space, computed
  here from ``biject_to(support)``; NumPyro's own ``_<name>_log_det`` factor sites are never created
  because the model is run with constrained values substituted, not through NumPyro's reparam);
- likelihood = Σ log p(observed sample sites), which includes every user ``numpyro.factor`` site
  (a factor is an observed ``Unit`` site).

With ``tempered`` (names of observed or factor sites) only those sites form the likelihood that TMCMC
tempers; every other observed site joins the base density with the prior (a run then starts from draws
of that base, e.g. an earlier posterior: :meth:`bubblecal.inference.tmcmc.TMCMC.run`).

Site ``scale`` (plates with subsampling, ``numpyro.handlers.scale``) and masks are honoured as in
``numpyro.infer.util.log_density``.

Data as arguments: the numeric array leaves of the model's arguments (``FlatModel.data``; the model's
``functools.partial`` arguments included) are passed to the densities as traced values rather than
closed over as constants, and ``FlatModel.signature`` identifies everything else (model function,
fixed arguments, array shapes, latent structure, bijections).  Two models with equal signatures
can therefore share one compiled program (e.g. curves of one network architecture and length).  A
model that needs the concrete values of its arrays (``np.asarray(x)``, ``float(y.max())``) is detected
by an abstract trace and keeps them as constants (``data == ()``, its signature then matches no other).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree
from numpyro import handlers
from numpyro.distributions import constraints
from numpyro.distributions.transforms import biject_to
from numpyro.distributions.util import is_identically_one, sum_rightmost
from numpyro.infer import Predictive

from bubblecal.inference.tmcmc._keys import DATA, _aval_key, _fingerprint, _static_key

# Uniform draws can land exactly on a bound in float32; the bijection then maps them to ±inf.
# Such (rare) draws are moved to this finite unconstrained value (a point within ~1e-9 of the bound).
_UNCONSTRAINED_CLIP = 20.0


def _site_log_prob(site) -> jax.Array:
    """Summed log density of a trace site, with its scale."""
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


#: placeholder of a traced argument among the fixed leaves of the model's arguments (an enum: a stable key)
_DATA = DATA


def _is_data(leaf) -> bool:
    """Numeric arrays are data (traced arguments); scalars, strings and objects stay fixed."""
    return isinstance(leaf, (np.ndarray, jax.Array)) and np.dtype(leaf.dtype).kind in "biuf"


def _has_tracer(tree) -> bool:
    """Whether any leaf of ``tree`` is a JAX tracer."""
    return any(isinstance(v, jax.core.Tracer) for v in jax.tree_util.tree_leaves(tree))


def _unpartial(model, args: tuple, kwargs: dict):
    """``partial(f, *a, **k)`` with ``args``/``kwargs`` -> ``(f, a + args, {**k, **kwargs})`` (nested too)."""
    while isinstance(model, functools.partial):
        args = tuple(model.args) + tuple(args)
        kwargs = {**model.keywords, **kwargs}
        model = model.func
    return model, args, kwargs


def _model_label(model) -> str:
    """Readable name of a model function for messages."""
    return getattr(model, "__qualname__", None) or getattr(model, "__name__", None) or repr(model)


class FlatModel:
    """A NumPyro model bound to its arguments, seen through one flat parameter vector.

    Parameters
    ----------
    model : callable
        NumPyro model (a ``functools.partial`` is unwrapped: its bound arguments are arguments too).
    model_args : tuple
        Positional arguments of the model.
    model_kwargs : dict or None
        Keyword arguments of the model.
    space : {'unconstrained', 'constrained'}
        'unconstrained': the vector is the unconstrained image of the latent sites and the prior
        includes log|J|. 'constrained': the vector holds the constrained values themselves (Korali's
        behaviour on box priors); the prior is −∞ outside each site's support.
    rng_key : jax.Array or None
        Key of the prototype draw that gives the sites and shapes (default ``PRNGKey(0)``).
    tempered : sequence of str or None
        Observed or factor sites that form the tempered likelihood; the other observed sites count with
        the prior (the base density). None (default): every observed and factor site is likelihood.

    Raises
    ------
    ValueError
        For an unknown ``space``, a discrete latent site, no continuous latent site, (constrained
        space) a support with event dimensions, or a ``tempered`` name that is no observed or factor site.
    """

    def __init__(
        self, model: Callable, model_args=(), model_kwargs=None, space="unconstrained", rng_key=None,
        tempered=None,
    ):
        if space not in ("unconstrained", "constrained"):
            raise ValueError(f"space must be 'unconstrained' or 'constrained', got {space!r}")
        # a partial's bound arguments are arguments like any other (its arrays become data)
        model, model_args, model_kwargs = _unpartial(model, tuple(model_args), dict(model_kwargs or {}))
        self.model = model
        self.label = _model_label(model)
        self.args = tuple(model_args)
        self.kwargs = dict(model_kwargs)
        self.space = space
        self.tempered = None if tempered is None else tuple(tempered)
        rng_key = jax.random.PRNGKey(0) if rng_key is None else rng_key
        # The prototype draw that gives the sites, supports and shapes is traced abstractly: run
        # eagerly, every new array shape of the model (each curve length, network) would compile
        # its operations one by one.  Supports computed from arrays inside the model are tracers
        # there; such models (and any that fail abstractly) take the eager draw as before.
        proto = self._abstract_prototype(rng_key)
        if proto is None:
            trace = handlers.trace(handlers.seed(model, rng_key)).get_trace(*self.args, **self.kwargs)
            self._read_sites(trace)
            proto_values = {k: trace[k]["value"] for k in self.latent}
            flat0, self._unravel = ravel_pytree(self._to_flat_space(proto_values))
        else:
            proto_values, flat0 = proto
        if self.tempered is not None:
            unknown = [k for k in self.tempered if k not in self.observed]
            if unknown or not self.tempered:
                raise ValueError(f"model {self.label!r}: tempered sites {unknown or list(self.tempered)} are not "
                                 f"among its observed and factor sites {self.observed}")
        self.dim = int(flat0.shape[0])
        self.dtype = flat0.dtype
        #: shape of one draw of each latent site
        self.latent_shapes = {k: tuple(jnp.shape(proto_values[k])) for k in self.latent}
        self._split_arguments(traced=True)
        if self.data and not self._traceable(flat0):
            self._split_arguments(traced=False)
        self.signature = (
            self.model,
            space,
            self._treedef,
            tuple(_static_key(v) for v in self._fixed),
            tuple(_aval_key(v) for v in self.data),
            tuple((k, tuple(jnp.shape(proto_values[k])), str(proto_values[k].dtype)) for k in self.latent),
            tuple(_fingerprint(self.transforms[k]) for k in self.latent),
            tuple(_fingerprint(self.scales[k]) for k in self.latent),
            tuple(self.event_dims[k] for k in self.latent),
            tuple(self.deterministic),
            self.tempered,
        )

    def _read_sites(self, trace) -> None:
        """Latent sites, their bijections, scales and event dims, and the deterministic sites of a trace."""
        self.latent: list[str] = []
        self.transforms = {}
        self.scales = {}
        self.event_dims = {}
        self.deterministic: list[str] = []
        self.observed: list[str] = []
        space = self.space
        for name, site in trace.items():
            if site["type"] == "deterministic":
                self.deterministic.append(name)
            if site["type"] == "sample" and site["is_observed"]:
                self.observed.append(name)
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

    def _abstract_prototype(self, rng_key):
        """(latent value shapes, flat vector shape) from an abstract trace, or None where it cannot serve."""
        box = {}

        def probe(key):
            box["trace"] = trace = handlers.trace(handlers.seed(self.model, key)).get_trace(*self.args, **self.kwargs)
            return {k: v["value"] for k, v in trace.items() if v["type"] == "sample" and not v["is_observed"]}

        try:
            values = jax.eval_shape(probe, rng_key)
        except Exception:  # noqa: BLE001 - whatever fails abstractly runs eagerly (and reports there)
            return None
        try:
            self._read_sites(box["trace"])
        except Exception:  # noqa: BLE001 - a support built from traced arrays (or a bad model): eager draw
            return None
        if _has_tracer((self.transforms, self.scales)):  # a support or scale computed in the model
            return None
        values = {k: values[k] for k in self.latent}

        def flatten(v):
            flat, box["unravel"] = ravel_pytree(self._to_flat_space(v))
            return flat

        flat0 = jax.eval_shape(flatten, values)
        self._unravel = box["unravel"]  # holds shapes and dtypes only, nothing of the trace
        return values, flat0

    # -- arguments: traced data and fixed rest --------------------------------------------------

    def _split_arguments(self, traced: bool) -> None:
        """Split the arguments' leaves into traced data (numeric arrays) and fixed values."""
        leaves, self._treedef = jax.tree_util.tree_flatten((self.args, self.kwargs))
        use = [traced and _is_data(v) for v in leaves]
        #: the traced arguments (numeric array leaves of args/kwargs), in tree order
        self.data = tuple(v for v, u in zip(leaves, use, strict=True) if u)
        self._fixed = [_DATA if u else v for v, u in zip(leaves, use, strict=True)]

    def _traceable(self, flat0) -> bool:
        """Whether the densities run with abstract data (no concrete value of an array needed)."""
        try:
            jax.eval_shape(lambda x, data: self.log_terms(x, data), flat0, self.data)
        except Exception:  # noqa: BLE001 - any failure: keep the arrays as constants, as before
            return False
        return True

    def arguments(self, data=None) -> tuple[tuple, dict]:
        """(args, kwargs) of the model with ``data`` (default: the bound arrays) in place of the arrays."""
        if data is None:
            return self.args, self.kwargs
        values = iter(data)
        leaves = [next(values) if v is _DATA else v for v in self._fixed]
        return jax.tree_util.tree_unflatten(self._treedef, leaves)

    # -- spaces -------------------------------------------------------------------------------

    def _to_flat_space(self, constrained: dict) -> dict:
        """Constrained values mapped to the flat space (clipped where a bound maps to ±inf)."""
        if self.space == "constrained":
            return dict(constrained)
        out = {}
        for k, v in constrained.items():
            u = self.transforms[k].inv(v)
            out[k] = jnp.where(jnp.isfinite(u), u, jnp.sign(u) * _UNCONSTRAINED_CLIP)
        return out

    def constrain(self, x: jax.Array) -> dict:
        """Constrained latent values {site: value} of one flat vector."""
        params = self._unravel(x)
        if self.space == "constrained":
            return params
        return {k: self.transforms[k](v) for k, v in params.items()}

    def flatten(self, constrained: dict) -> jax.Array:
        """The flat vector of constrained latent values {site: value} (inverse of :meth:`constrain`)."""
        return ravel_pytree(self._to_flat_space({k: constrained[k] for k in self.latent}))[0]

    # -- densities ----------------------------------------------------------------------------

    def _trace(self, values: dict, data=None):
        """Trace of the model with ``values`` substituted for the latent sites."""
        model = handlers.substitute(handlers.seed(self.model, jax.random.PRNGKey(0)), data=values)
        args, kwargs = self.arguments(data)
        return handlers.trace(model).get_trace(*args, **kwargs)

    def _values_and_jacobian(self, x: jax.Array) -> tuple[dict, jax.Array]:
        """Constrained latent values of one flat vector and log|J| of the map to them (0 in constrained space)."""
        params = self._unravel(x)
        log_jac = jnp.zeros((), self.dtype)
        if self.space == "constrained":
            return params, log_jac
        values = {}
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
        return values, log_jac

    def _latent_log_prob(self, site) -> jax.Array:
        """Log density of a latent site (−∞ outside its support in constrained space)."""
        lp = _site_log_prob(site)
        if self.space == "constrained":
            lp = jnp.where(jnp.all(site["fn"].support(site["value"])), lp, -jnp.inf)
        return lp

    def log_terms(self, x: jax.Array, data=None) -> tuple[jax.Array, jax.Array]:
        """(log prior in the flat space, log likelihood) of one flat vector (``data``: see :meth:`arguments`);
        with ``tempered``, (log base density, log tempered likelihood)."""
        values, log_prior = self._values_and_jacobian(x)
        log_lik = jnp.zeros((), self.dtype)
        for name, site in self._trace(values, data).items():
            if site["type"] != "sample":
                continue
            if site["is_observed"] and (self.tempered is not None and name not in self.tempered):
                log_prior = log_prior + _site_log_prob(site)
            elif site["is_observed"]:
                log_lik = log_lik + _site_log_prob(site)
            elif name in self.transforms:
                log_prior = log_prior + self._latent_log_prob(site)
        return log_prior, log_lik

    def model_log_prior(self, x: jax.Array, data=None) -> jax.Array:
        """Log prior of one flat vector in the flat space: the latent sites only, also with ``tempered`` (the
        likelihood's arrays are traced but unused, so the compiler drops them)."""
        values, log_prior = self._values_and_jacobian(x)
        for name, site in self._trace(values, data).items():
            if site["type"] == "sample" and not site["is_observed"] and name in self.transforms:
                log_prior = log_prior + self._latent_log_prob(site)
        return log_prior

    def log_prior(self, x, data=None):
        """Log prior of one flat vector, in the flat space (see :meth:`log_terms`)."""
        return self.log_terms(x, data)[0]

    def log_likelihood(self, x, data=None):
        """Log likelihood of one flat vector: observed sites and user factors (see :meth:`log_terms`)."""
        return self.log_terms(x, data)[1]

    def sites(self, x: jax.Array, data=None) -> dict:
        """Constrained latent values and deterministic sites of one flat vector."""
        values = self.constrain(x)
        out = dict(values)
        if self.deterministic:
            tr = self._trace(values, data)
            for name in self.deterministic:
                out[name] = tr[name]["value"]
        return out

    # -- prior draws --------------------------------------------------------------------------

    def prior_draws(self, rng_key, num: int, data=None) -> jax.Array:
        """Exact prior draws (NumPyro ``Predictive``), mapped to the flat space: shape (num, dim)."""
        pred = Predictive(self.model, num_samples=num, return_sites=self.latent, parallel=True)
        args, kwargs = self.arguments(data)
        draws = pred(rng_key, *args, **kwargs)
        return jax.vmap(self.flatten)(draws)
