"""JAX functions the summaries and figures evaluate on host data, each as one compiled program.

Called eagerly, a JAX function compiles one XLA program per operation and shape (an acoustic law over 5,000 draws:
about twenty), which on a GPU costs a tenth of a second or more each in a cold run.  Jitted, each costs one program
per shape, read back from the persistent compilation cache in a warm run.  Programs are kept per surrogate object
(the object is held, so its identity stays valid) and per static setting.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

import numpy as np

__all__ = ["acoustic_prediction_program", "frequency_program", "population_predictive_draws"]

_PROGRAMS: dict = {}


def _program(key: tuple, owner, build: Callable) -> Callable:
    """``build()`` once per ``key`` (``owner`` kept alive beside it, so an ``id`` in the key stays its own)."""
    entry = _PROGRAMS.get(key)
    if entry is None or entry[0] is not owner:
        entry = _PROGRAMS[key] = (owner, build())
    return entry[1]


def acoustic_prediction_program(f_res) -> Callable:
    """Compiled :func:`bubblecal.models.acoustic.acoustic_prediction` of the acoustic surrogate ``f_res``.

    Parameters
    ----------
    f_res : callable or object
        Acoustic surrogate (as :func:`~bubblecal.models.acoustic.acoustic_prediction` takes it).

    Returns
    -------
    callable
        ``(ka_samples (S,), sigma_samples (S,), diameters: tuple of float [µm], f_scale: float [MHz]) ->
        (fhat, sd)``, each (S, n) [MHz] as NumPy arrays; ``diameters`` and ``f_scale`` are static.
    """
    import jax

    from bubblecal.models.acoustic import acoustic_prediction

    def build():
        fn = jax.jit(lambda ka, sigma, diameters, f_scale: acoustic_prediction(
            ka, sigma, f_res, np.asarray(diameters, dtype=float), f_scale=f_scale), static_argnums=(2, 3))

        def call(ka, sigma, diameters, f_scale):
            mu, sd = fn(np.asarray(ka), np.asarray(sigma), tuple(float(d) for d in diameters), float(f_scale))
            return np.asarray(mu, dtype=float), np.asarray(sd, dtype=float)

        return call

    return _program(("acoustic_prediction", id(f_res)), f_res, build)


def frequency_program(f_res) -> Callable:
    """Compiled resonance frequency of the acoustic surrogate ``f_res``.

    Parameters
    ----------
    f_res : callable or object
        Acoustic surrogate: a callable ``(ka, diameter_um) -> MHz`` or an object with such an ``f_res`` method.

    Returns
    -------
    callable
        ``(ka, diameter_um) -> MHz`` on broadcasting host arrays, as a NumPy array; the diameters are constants of
        the program (surrogates fitted per diameter look them up), one program per set of diameters and shapes.
    """
    import jax

    from bubblecal.models.acoustic import as_fres

    def call(ka, diameter_um):
        ka = np.asarray(ka)
        d = np.asarray(diameter_um, dtype=float)
        key = ("frequency", id(f_res), d.shape, d.tobytes())  # jit keeps one executable per shape of ka
        fn = _program(key, f_res, lambda: jax.jit(lambda k: as_fres(f_res)(k, d)))
        return np.asarray(fn(ka))

    return call


def population_predictive_draws(rng_key, m_samples: Mapping, tau_samples: Mapping, bounds: Mapping,
                                num: int) -> dict[str, np.ndarray]:
    """:func:`bubblecal.models.sample_population_predictive` as one compiled program, NumPy results.

    Parameters
    ----------
    rng_key : jax.Array
        PRNG key.
    m_samples, tau_samples : mapping of str to array_like
        Parameter -> (S,) draws of ψ (DPD units).
    bounds : mapping of str to (float, float)
        Prior range of each parameter.
    num : int
        Draws.

    Returns
    -------
    dict of str to numpy.ndarray
        Parameter -> (num,) draws of a new bubble's parameters.
    """
    import jax

    from bubblecal.models import sample_population_predictive

    frozen = tuple((k, (float(lo), float(hi))) for k, (lo, hi) in bounds.items())
    fn = _program(("population", frozen, int(num)), None, lambda: jax.jit(
        lambda key, m, tau: sample_population_predictive(key, m, tau, dict(frozen), int(num))))
    m = {k: np.asarray(v) for k, v in m_samples.items()}
    tau = {k: np.asarray(v) for k, v in tau_samples.items()}
    return {k: np.asarray(v) for k, v in fn(rng_key, m, tau).items()}
