"""TMCMC benchmark: bubblecal's compiled TMCMC core vs BlackJAX 1.7.1 ``adaptive_tempered_smc``.

Likelihood (surrogate-shaped): a random tanh MLP 7→128×4→1 with softplus output,
evaluated at 24 points; parameters (k_a, k_b, b1, b2, a3, a4, d0, σ) under an 8-parameter box prior;
compression-style input x̃ = max(0, x − d0); multiplicative Gaussian noise y ~ N(ŷ, (σŷ)²) with data
drawn at 5 % noise.  Both samplers: the same N, likelihood, box prior in the original space, RW-MH
from the particle covariance, 10 MH steps per stage, target ESS 0.5 (bubblecal: target CoV 1.0,
ESS/N = 1/(1+CoV²) = 0.5), systematic resampling.  bubblecal's RW scale adapts toward acceptance
0.3; BlackJAX uses the fixed optimal scale 2.38/√d.

Reported: wall time of a run after compilation (median over ``--repeats``), stages, likelihood
evaluations and evaluations/s, log Z; the floor = (evaluations / N) × (time of one jitted vmapped
evaluation of all N particles); the bubblecal/BlackJAX time ratio; and, with ``--replicas R``,
time-to-accuracy: from R independent runs, the per-run sd of log Z and the per-run ESS of every
parameter (posterior variance / variance of the run's posterior mean across runs); the runs needed
for SE(log Z) ≤ 0.1 and ESS ≥ 1,000 for every parameter are k = max(⌈(sd/0.1)²⌉, ⌈1000/ESS_min⌉),
and time-to-accuracy = k × (time per run).

    python benchmarks/tmcmc.py --n 5000 --device cpu            # 2 CPU cores
    python benchmarks/tmcmc.py --n 50000 --device gpu           # H100
The last line printed is one JSON object with every number.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import sys
import time


def _parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=5000, help="number of particles N")
    p.add_argument("--device", choices=("cpu", "gpu"), default="cpu")
    p.add_argument("--steps", type=int, default=10, help="MH steps per stage")
    p.add_argument("--repeats", type=int, default=3, help="timed runs after the compile run")
    p.add_argument("--replicas", type=int, default=0, help="independent runs for time-to-accuracy (0: skip)")
    p.add_argument(
        "--moves",
        default="rw",
        help="comma list of bubblecal moves: rw (box), rw-u (logit space), hmc (logit space)",
    )
    p.add_argument("--hmc-steps", type=int, default=3, help="HMC transitions per stage for --moves hmc")
    p.add_argument("--no-blackjax", action="store_true", help="skip BlackJAX")
    p.add_argument("--chunk-size", type=int, default=None)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--problem", choices=("surrogate", "ridge"), default="surrogate")
    return p.parse_args()


ARGS = _parse() if __name__ == "__main__" else None
if ARGS is not None:
    os.environ.setdefault("JAX_PLATFORMS", "cpu" if ARGS.device == "cpu" else "cuda")

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
from bubblecal._extras import require  # noqa: E402
from bubblecal.inference import tmcmc as core  # noqa: E402

D = 8
NAMES = ("ka", "kb", "b1", "b2", "a3", "a4", "d0", "sigma")
LO = np.array([-1, -1, -1, -1, -1, -1, 0.0, 0.01])
HI = np.array([1, 1, 1, 1, 1, 1, 0.2, 0.2])
NOISE_FLOOR = 1e-6  # floor on the sd (σ ŷ) so a prediction of 0 keeps the density finite


def make_problem(seed: int = 0, n_points: int = 24):
    """(log_prior_fn, log_likelihood_fn, theta_true) of the surrogate-shaped problem."""
    rng = np.random.default_rng(seed)
    sizes = [7, 128, 128, 128, 128, 1]
    params = []
    for fin, fout in zip(sizes[:-1], sizes[1:], strict=True):
        params.append(
            (
                rng.normal(0, 1.0 / math.sqrt(fin), (fin, fout)).astype(np.float32),
                rng.normal(0, 0.1, fout).astype(np.float32),
            )
        )
    params = [(jnp.asarray(w), jnp.asarray(b)) for w, b in params]
    x = jnp.linspace(0.0, 1.0, n_points, dtype=jnp.float32)
    lo, hi = jnp.asarray(LO, jnp.float32), jnp.asarray(HI, jnp.float32)
    log_vol = float(np.log(HI - LO).sum())

    def predict(theta):
        shape, d0 = theta[:6], theta[6]
        xt = jnp.maximum(0.0, x - d0)
        h = jnp.concatenate([jnp.broadcast_to(shape, (n_points, 6)), xt[:, None]], axis=1)
        for w, b in params[:-1]:
            h = jnp.tanh(h @ w + b)
        w, b = params[-1]
        return jax.nn.softplus(h @ w + b)[:, 0]

    theta_true = np.concatenate([rng.uniform(-0.6, 0.6, 6), [0.05, 0.05]]).astype(np.float32)
    y_hat = np.asarray(predict(jnp.asarray(theta_true)))
    y = jnp.asarray(y_hat * (1 + 0.05 * rng.normal(size=n_points)), jnp.float32)

    def log_prior(theta):
        inside = jnp.all((theta >= lo) & (theta <= hi))
        return jnp.where(inside, -log_vol, -jnp.inf)

    def log_likelihood(theta):
        y_pred = predict(theta)
        sd = jnp.maximum(theta[7] * y_pred, NOISE_FLOOR)
        return jnp.sum(-0.5 * ((y - y_pred) / sd) ** 2 - jnp.log(sd) - 0.5 * math.log(2 * math.pi))

    return log_prior, log_likelihood, theta_true


def make_ridge_problem(width: float = 0.02):
    """A curved narrow k_a–k_b ridge (k_a ≈ k_b², width ``width``) plus 6 well-identified parameters,
    on the same 8-parameter box: to compare random-walk and gradient moves."""
    lo, hi = jnp.asarray(LO, jnp.float32), jnp.asarray(HI, jnp.float32)
    log_vol = float(np.log(HI - LO).sum())
    centre = jnp.asarray(LO + 0.6 * (HI - LO), jnp.float32)
    spread = jnp.asarray(0.1 * (HI - LO), jnp.float32)

    def log_prior(theta):
        inside = jnp.all((theta >= lo) & (theta <= hi))
        return jnp.where(inside, -log_vol, -jnp.inf)

    def log_likelihood(theta):
        ka, kb = theta[0], theta[1]
        ridge = -0.5 * ((ka - kb**2 + 0.3) / width) ** 2 - 0.5 * ((ka + kb) / 0.6) ** 2
        rest = -0.5 * jnp.sum(((theta[2:] - centre[2:]) / spread[2:]) ** 2)
        return ridge + rest

    return log_prior, log_likelihood, None


def unconstrained(log_likelihood):
    """The same problem in u = logit((θ − lo)/(hi − lo)): (log prior incl. log|J|, log L, u ↦ θ, θ ↦ u)."""
    lo, width = jnp.asarray(LO, jnp.float32), jnp.asarray(HI - LO, jnp.float32)

    def to_theta(u):
        return lo + width * jax.nn.sigmoid(u)

    def to_u(theta):
        p = jnp.clip((theta - lo) / width, 1e-7, 1 - 1e-7)
        return jnp.log(p) - jnp.log1p(-p)

    def log_prior_u(u):  # uniform box: density 1/vol times |dθ/du|
        return jnp.sum(jnp.log(width) + jax.nn.log_sigmoid(u) + jax.nn.log_sigmoid(-u)) - jnp.sum(
            jnp.log(width)
        )

    return log_prior_u, lambda u: log_likelihood(to_theta(u)), to_theta, to_u


def prior_draws(key, n):
    return jax.random.uniform(
        key, (n, D), jnp.float32, jnp.asarray(LO, jnp.float32), jnp.asarray(HI, jnp.float32)
    )


def _block(x):
    return jax.tree_util.tree_map(lambda a: a.block_until_ready(), x)


# ------------------------------------------------------------------------------------------------


def bubblecal_runner(log_prior, log_lik, n, steps, move_name, chunk_size, hmc_steps):
    """'rw': RW in the box (as BlackJAX); 'rw-u': RW in logit space; 'hmc': NumPyro HMC in logit space."""
    to_theta = None
    if move_name in ("rw-u", "hmc"):
        log_prior, log_lik, to_theta, to_u = unconstrained(log_lik)
    if move_name in ("rw", "rw-u"):
        move = core.RandomWalk(num_steps=steps, init_scale2=0.04, adapt=True)
    elif move_name == "hmc":
        from bubblecal.inference import hmc_move

        move = hmc_move(num_steps=hmc_steps, trajectory_length=1.5)
    else:
        raise ValueError(f"unknown move {move_name!r}")
    alg = core.tmcmc(log_prior, log_lik, move, core.TMCMCConfig(target_cov=1.0, chunk_size=chunk_size), 200)

    @jax.jit
    def whole(key):
        k0, k1 = jax.random.split(key)
        x0 = prior_draws(k0, n)
        state = alg.init(x0 if to_theta is None else jax.vmap(to_u)(x0))
        final, infos, status = alg.run(k1, state)
        if to_theta is not None:
            final = final._replace(position=jax.vmap(to_theta)(final.position))
        return final, infos, status

    def run(key):
        final, infos, status = _block(whole(key))
        return {
            "log_z": float(final.log_evidence),
            "stages": int(final.stage),
            "evals": int(final.num_evaluations),
            "status": core.STATUS_NAMES[int(status)],
            "particles": np.asarray(final.position),
            "acceptance": float(np.nanmean(np.asarray(infos.acceptance)[: int(final.stage)])),
        }

    return run


def blackjax_runner(log_prior, log_lik, n, steps):
    blackjax = require("blackjax", "bench")  # names the [bench] extra when it is missing
    from blackjax.mcmc.random_walk import build_additive_step, normal
    from blackjax.smc import resampling
    from blackjax.smc.base import extend_params

    rw = build_additive_step()
    scale = 2.38 / math.sqrt(D)

    def step_fn(key, state, logdensity_fn, chol):
        return rw(key, state, logdensity_fn, normal(chol))

    def update(key, state, info):
        x = state.particles
        cov = jnp.cov(x.T) + 1e-8 * jnp.eye(D)
        return extend_params({"chol": scale * jnp.linalg.cholesky(cov)})

    def rw_init(position, logdensity_fn):
        return blackjax.rmh.init(position, logdensity_fn)

    alg = blackjax.inner_kernel_tuning(
        smc_algorithm=blackjax.adaptive_tempered_smc,
        logprior_fn=log_prior,
        loglikelihood_fn=log_lik,
        mcmc_step_fn=step_fn,
        mcmc_init_fn=rw_init,
        resampling_fn=resampling.systematic,
        mcmc_parameter_update_fn=update,
        initial_parameter_value=extend_params(
            {"chol": 0.2 * jnp.diag(jnp.asarray(HI - LO, jnp.float32)) / math.sqrt(12)}
        ),
        num_mcmc_steps=steps,
        target_ess=0.5,
    )
    init_fn = jax.jit(alg.init)
    step = jax.jit(alg.step)

    def run(key):
        k0, key = jax.random.split(key)
        state = init_fn(prior_draws(k0, n))
        log_z, stages = 0.0, 0
        # the usual BlackJAX driver: a host loop over jitted steps, reading λ each stage
        while float(state.sampler_state.tempering_param) < 1.0 and stages < 200:
            key, sub = jax.random.split(key)
            state, info = step(sub, state)
            log_z += info.log_likelihood_increment
            stages += 1
        _block(state)
        return {
            "log_z": float(log_z),
            "stages": stages,
            "evals": n + stages * steps * n,
            "status": "converged" if float(state.sampler_state.tempering_param) >= 1.0 else "max_stages",
            "particles": np.asarray(state.sampler_state.particles),
            "acceptance": float("nan"),
        }

    return run


def time_eval(ev, x, reps=5):
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        _block(ev(x))
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def accuracy(run, seed, replicas, t_run):
    zs, means, variances = [], [], []
    for r in range(replicas):
        res = run(jax.random.PRNGKey(seed + 5000 + r))
        zs.append(res["log_z"])
        means.append(res["particles"].mean(0))
        variances.append(res["particles"].var(0))
    zs, means = np.array(zs), np.array(means)
    sd_z = float(zs.std(ddof=1))
    ess = np.array(variances).mean(0) / means.var(0, ddof=1)
    k = max(math.ceil((sd_z / 0.1) ** 2), math.ceil(1000.0 / ess.min()), 1)
    return {
        "replicas": replicas,
        "log_z_mean": float(zs.mean()),
        "log_z_sd_per_run": sd_z,
        "ess_per_run_min": float(ess.min()),
        "ess_per_run": {nm: float(e) for nm, e in zip(NAMES, ess, strict=True)},
        "runs_needed": k,
        "time_to_accuracy_s": k * t_run,
    }


def main(args):
    if args.problem == "surrogate":
        log_prior, log_lik, _ = make_problem(args.seed)
    else:
        log_prior, log_lik, _ = make_ridge_problem()
    n = args.n
    dev = jax.devices()[0]
    out = {
        "benchmark": "tmcmc",
        "problem": args.problem,
        "n": n,
        "steps": args.steps,
        "device": f"{dev.platform}:{getattr(dev, 'device_kind', '')}",
        "cpu_count": os.cpu_count(),
        "jax": jax.__version__,
        "python": platform.python_version(),
        "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "load_average_at_start": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        "rows": {},
    }

    # floor: one jitted vmapped evaluation of all particles (median of 5, re-measured every repeat)
    x = prior_draws(jax.random.PRNGKey(99), n)
    ev = jax.jit(jax.vmap(log_lik))
    _block(ev(x))

    runners = {}
    for mv in [m.strip() for m in args.moves.split(",") if m.strip()]:
        runners[f"bubblecal-{mv}"] = bubblecal_runner(
            log_prior, log_lik, n, args.steps, mv, args.chunk_size, args.hmc_steps
        )
    if not args.no_blackjax:
        runners["blackjax"] = blackjax_runner(log_prior, log_lik, n, args.steps)

    # compile every runner, then interleave the timed repeats (and the floor measurement) so that a
    # changing background load on the machine hits every sampler alike
    compile_s, times, results = {}, {k: [] for k in runners}, {k: [] for k in runners}
    for name, run in runners.items():
        t0 = time.perf_counter()
        run(jax.random.PRNGKey(args.seed + 1000))
        compile_s[name] = time.perf_counter() - t0
    eval_times = []
    for r in range(args.repeats):
        eval_times.append(time_eval(ev, x))
        for name, run in runners.items():
            t0 = time.perf_counter()
            results[name].append(run(jax.random.PRNGKey(args.seed + r)))
            times[name].append(time.perf_counter() - t0)
    t_eval = float(np.median(eval_times))
    out["t_eval_all_particles_s"] = t_eval

    for name, run in runners.items():
        compile_first, ts, res = compile_s[name], times[name], results[name]
        t = float(np.median(ts))
        evals = res[0]["evals"]
        row = {
            "wall_s": t,
            "wall_all_s": ts,
            "first_run_incl_compile_s": compile_first,
            "stages": res[0]["stages"],
            "evaluations": evals,
            "evals_per_s": evals / t,
            "log_z": [r["log_z"] for r in res],
            "status": res[0]["status"],
            "mean_acceptance": res[0]["acceptance"],
            "floor_s": (evals / n) * t_eval,
        }
        row["x_floor"] = t / row["floor_s"]
        if args.replicas >= 2:
            row["accuracy"] = accuracy(run, args.seed, args.replicas, t)
        out["rows"][name] = row

    if "blackjax" in out["rows"]:
        for row in out["rows"].values():
            row["ratio_vs_blackjax"] = row["wall_s"] / out["rows"]["blackjax"]["wall_s"]
            if "accuracy" in row and "accuracy" in out["rows"]["blackjax"]:
                row["tta_ratio_vs_blackjax"] = (
                    row["accuracy"]["time_to_accuracy_s"]
                    / out["rows"]["blackjax"]["accuracy"]["time_to_accuracy_s"]
                )

    print(
        f"TMCMC benchmark: N = {n}, {args.steps} MH steps/stage, device {out['device']}, "
        f"one vmapped evaluation of all particles {t_eval * 1e3:.2f} ms"
    )
    hdr = (f"{'sampler':>14s} {'wall s':>8s} {'stages':>6s} {'evals':>10s} {'evals/s':>10s} {'floor s':>8s} "
           f"{'x floor':>7s} {'vs BJ':>6s} {'log Z':>9s}")
    extra = (
        f" {'sdZ/run':>8s} {'ESSmin/run':>10s} {'TTA s':>8s} {'TTA vs BJ':>9s}" if args.replicas >= 2 else ""
    )
    print(hdr + extra)
    for name, row in out["rows"].items():
        line = (
            f"{name:>14s} {row['wall_s']:8.3f} {row['stages']:6d} {row['evaluations']:10d} "
            f"{row['evals_per_s']:10.3g} {row['floor_s']:8.3f} {row['x_floor']:7.2f} "
            f"{row.get('ratio_vs_blackjax', float('nan')):6.2f} {np.mean(row['log_z']):9.3f}"
        )
        if "accuracy" in row:
            a = row["accuracy"]
            line += (
                f" {a['log_z_sd_per_run']:8.3f} {a['ess_per_run_min']:10.1f} {a['time_to_accuracy_s']:8.2f}"
                f" {row.get('tta_ratio_vs_blackjax', float('nan')):9.2f}"
            )
        print(line)
    print(json.dumps(out))
    return out


if __name__ == "__main__":
    main(ARGS)
