"""run_staged(batch=True): phase-1 and phase-3 datasets of one structure run as batches, stored phases are not
rerun, every finished phase is saved and reported; phase 2 stays one run."""

from __future__ import annotations

import functools

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest

import bubblecal.inference._phase_batch as phase_batch
import bubblecal.inference.hierarchical as hierarchical
from bubblecal.inference import Dataset, PhaseResult, run_staged

BOX = (-10.0, 10.0)


def curve_model(y, s, population=None):
    theta = numpyro.sample("theta", dist.Uniform(*BOX))
    if population is not None:
        m, tau = population
        numpyro.factor("population_prior", dist.Normal(m, tau).log_prob(theta).mean())
    numpyro.sample("y", dist.Normal(theta, s), obs=y)


def phase2_factory(samples, names):
    def model():
        m = numpyro.sample("m_theta", dist.Uniform(-3.0, 3.0))
        tau = numpyro.sample("tau_theta", dist.Uniform(0.05, 3.0))
        numpyro.factor("population_likelihood", sum(dist.Normal(m, tau).log_prob(d["theta"]).mean() for d in samples))

    return model


def phase3_factory(datasets):
    def factory(i, m_samples, tau_samples):
        # a partial: its arrays are arguments, so the phase-3 models of equal shapes form one batch
        return functools.partial(curve_model, *datasets[i].args,
                                 population=(np.asarray(m_samples["theta"]), np.asarray(tau_samples["theta"])))

    return factory


def make_datasets():
    """b0, b1, b3 have 3 observations, b2 has 2: two structures."""
    rng = np.random.default_rng(0)
    sizes = {"b0": 3, "b1": 3, "b2": 2, "b3": 3}
    return [Dataset(name, curve_model, (rng.normal(0.5, 1.0, size=n), np.full(n, 0.5))) for name, n in sizes.items()]


class FakeSampler:
    """What run_phases reads of a finished TMCMC."""

    def __init__(self, label, status="converged"):
        self.status = status
        self.log_evidence, self.log_evidence_se = -1.0, 0.1
        self._results = [{"seconds": 2.0}]
        self.label = label

    def get_samples(self):
        draws = np.linspace(-1.0, 1.0, 50)
        return {"theta": draws, "m_theta": draws, "tau_theta": 1.0 + draws**2}


@pytest.fixture
def fake_runs(monkeypatch):
    """Replace the TMCMC runs by fakes; records the batches and the one-by-one phases."""
    calls = {"batches": [], "single": []}

    def fake_batched(models, args_list, kwargs_list, keys, *, batch_size=None, callback=None, **options):
        calls["batches"].append([getattr(m, "func", m).__name__ + str(np.shape(a[0] if a else m.args[0]))
                                 for m, a in zip(models, args_list, strict=True)])
        out = [FakeSampler(f"run{i}", status=options.get("fail", {}).get(i, "converged")) for i in range(len(models))]
        for i, s in enumerate(out):
            callback(i, s)
        return out

    def fake_phase(name, model, args, kwargs, key, options, start=None):
        calls["single"].append(name)
        return hierarchical._phase_result(name, FakeSampler(name), 2.0)

    monkeypatch.setattr(phase_batch, "run_batched", fake_batched)
    monkeypatch.setattr(hierarchical, "run_phase", fake_phase)
    return calls


def test_batch_groups_phases_by_structure_and_skips_stored_ones(fake_runs):
    datasets = make_datasets()
    stored = {"phase1_b1": PhaseResult("phase1_b1", {"theta": np.zeros(50)}, -2.0, 0.0, "converged", 0.0),
              "phase3_b0": PhaseResult("phase3_b0", {"theta": np.zeros(50)}, -2.0, 0.0, "converged", 0.0)}
    saved, messages = [], []
    result = run_staged(datasets, phase2_factory, phase3_factory(datasets), jax.random.PRNGKey(0), batch=True,
                        load=stored.get, save=lambda r: saved.append(r.name), progress=messages.append)
    # phase 1: b1 reused; b0 and b3 (3 points) one batch; b2 (2 points) alone, one by one like phase 2
    # phase 3: b0 reused; b1 and b3 one batch; b2 alone
    assert fake_runs["batches"] == [["curve_model(3,)", "curve_model(3,)"], ["curve_model(3,)", "curve_model(3,)"]]
    assert fake_runs["single"] == ["phase1_b2", "phase2", "phase3_b2"]
    assert sorted(saved) == sorted(["phase1_b0", "phase1_b3", "phase1_b2", "phase2", "phase3_b1", "phase3_b3",
                                    "phase3_b2"])
    assert [r.name for r in result.phase1] == ["phase1_b0", "phase1_b1", "phase1_b2", "phase1_b3"]
    assert [r.name for r in result.phase3] == ["phase3_b0", "phase3_b1", "phase3_b2", "phase3_b3"]
    assert result.phase1[1] is stored["phase1_b1"] and result.phase3[0] is stored["phase3_b0"]
    assert "phase1_b1: reused (log Z = -2.000)" in messages
    assert "phase1_b0: running TMCMC (batch of 2)" in messages
    assert "phase1_b3: log Z = -1.000, 2.0 s (share of a batch of 2)" in messages


def test_batch_saves_the_converged_and_raises_for_the_others(fake_runs):
    datasets = make_datasets()
    saved = []
    with pytest.raises(RuntimeError, match=r"phase 'phase1_b3': .*'max_stages'"):
        run_staged(datasets, phase2_factory, phase3_factory(datasets), jax.random.PRNGKey(0), batch=True,
                   phase1_options={"fail": {2: "max_stages"}}, save=lambda r: saved.append(r.name))
    assert saved == ["phase1_b0", "phase1_b1"]  # b3 not saved; b2 (the next group) never ran


@pytest.mark.slow
def test_batched_staged_run_equals_the_sequential_fused_one(same_tempering):
    datasets = make_datasets()
    options = {"num_particles": 400, "compiled": True}
    kwargs = {"phase1_options": options, "phase2_options": options, "phase3_options": options}
    one_by_one = run_staged(datasets, phase2_factory, phase3_factory(datasets), jax.random.PRNGKey(1), **kwargs)
    # phase 2 taken from the sequential run: round-off of phase 1 (1e-6) could flip an accept/reject decision of
    # phase 2 and so change its draws; given the same ψ draws, phase 3 must agree to round-off too
    batched = run_staged(datasets, phase2_factory, phase3_factory(datasets), jax.random.PRNGKey(1), batch=True,
                         load={"phase2": one_by_one.phase2}.get, **kwargs)
    strict = []
    for a, b in zip(one_by_one.phase1 + one_by_one.phase3, batched.phase1 + batched.phase3, strict=True):
        assert a.name == b.name and b.sampler is not None
        strict.append(same_tempering(a.sampler, b.sampler))  # to round-off (see tests/inference/conftest.py)
    assert sum(strict) >= 4  # most phases compared particle by particle to the end
