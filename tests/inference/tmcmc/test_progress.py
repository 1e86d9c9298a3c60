"""Progress of the samplers: TMCMC reports every stage row, NUTS shows its phases, and neither changes the draws."""

from __future__ import annotations

import io

import jax
import numpy as np
import numpyro
import numpyro.distributions as dist
import pytest
from rich.console import Console

from bubblecal._progress import ProgressLine
from bubblecal.inference import TMCMC, run_nuts
from bubblecal.inference.tmcmc import STAGE_COLUMNS, StageDisplay, stage_text
from bubblecal.inference.tmcmc.progress import stage_reporter


def model_gauss(y):
    mu = numpyro.sample("mu", dist.Normal(0.0, 1.0))
    numpyro.sample("y", dist.Normal(mu, 0.5), obs=y)


Y = np.array([0.4, 0.1, 0.7])


@pytest.mark.parametrize("compiled", [False, True])
def test_tmcmc_reports_every_stage_row_and_keeps_the_draws(compiled):
    rows = []
    quiet = TMCMC(model_gauss, num_particles=400, num_replicas=2, compiled=compiled).run(jax.random.PRNGKey(7), Y)
    loud = TMCMC(model_gauss, num_particles=400, num_replicas=2, compiled=compiled,
                 progress=lambda replica, row: rows.append((replica, dict(row)))).run(jax.random.PRNGKey(7), Y)
    np.testing.assert_array_equal(quiet.get_samples()["mu"], loud.get_samples()["mu"])
    np.testing.assert_array_equal(quiet.log_evidences, loud.log_evidences)
    # one report per row of each replica's stage table, in order, with the table's values
    for r in range(2):
        table = loud.replica_stage_info(r)
        reported = [row for replica, row in rows if replica == r]
        assert [row["stage"] for row in reported] == list(range(len(table)))
        assert set(reported[-1]) == set(STAGE_COLUMNS)
        np.testing.assert_array_equal([row["beta"] for row in reported], table["beta"].to_numpy())
        np.testing.assert_array_equal([row["log_evidence"] for row in reported], table["log_evidence"].to_numpy())
    assert rows[-1][1]["beta"] == 1.0


def test_tmcmc_rich_display_keeps_the_draws():
    quiet = TMCMC(model_gauss, num_particles=300).run(jax.random.PRNGKey(3), Y)
    shown = TMCMC(model_gauss, num_particles=300, progress=True).run(jax.random.PRNGKey(3), Y)
    np.testing.assert_array_equal(quiet.get_samples()["mu"], shown.get_samples()["mu"])


def test_tmcmc_progress_must_be_bool_or_callable():
    with pytest.raises(ValueError, match="progress must be True, False or a callable"):
        TMCMC(model_gauss, progress="yes")
    with pytest.raises(ValueError, match="progress must be True, False or a callable"):
        stage_reporter(3, "m", 1)


def test_stage_text_names_stage_beta_ess_acceptance_and_log_z():
    row = {"stage": 4, "beta": 0.03125, "ess": 1612.4, "acceptance": 0.291, "log_evidence": -41.2071}
    assert stage_text(row) == "stage 4  beta 0.03125  ESS 1612  acc 0.29  log Z -41.207"
    assert "acc -" in stage_text({**row, "stage": 0, "acceptance": float("nan")})


def test_stage_display_draws_the_stage_line():
    buf = io.StringIO()
    console = Console(file=buf, force_terminal=True, width=160)
    display = StageDisplay("TMCMC m", num_replicas=2, console=console)
    display(1, {"stage": 2, "beta": 0.5, "ess": 300.0, "acceptance": 0.4, "log_evidence": -3.5})
    console.print(buf.getvalue() and "")  # let the live display refresh once
    display._line._bar.refresh()
    display.close()
    text = buf.getvalue()
    assert "replica 2/2" in text and "stage 2  beta 0.5  ESS 300  acc 0.40  log Z -3.500" in text


def test_disabled_progress_line_is_inert():
    line = ProgressLine("x", total=3, enabled=False)
    line.update(advance=1, info="i")
    line.close()
    assert line._bar is None


def test_nuts_progress_shows_phases_and_keeps_the_draws():
    kw = dict(rng_key=jax.random.PRNGKey(5), num_warmup=30, num_samples=25, num_chains=2)
    quiet = run_nuts(model_gauss, Y, **kw)
    shown = run_nuts(model_gauss, Y, progress=True, **kw)
    np.testing.assert_array_equal(quiet.samples["mu"], shown.samples["mu"])
    assert quiet.num_divergences == shown.num_divergences
    assert shown.samples_by_chain["mu"].shape == (2, 25)
