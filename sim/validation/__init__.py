"""bubblecal.sim.validation: the physics checks of docs/physics.md section 6 and ``bubblecal sim verify``.

* :func:`run_checks` / :func:`all_checks` (``verify``): every check behind one call, rendered as a table and a
  JSON line by ``bubblecal sim verify``;
* the checks: fluid, gas and impermeability (``fluid_checks``), shell (``checks``) and the Reissner point load
  (``reissner``), each returning a :class:`CheckResult` (``result``);
* :mod:`~bubblecal.sim.validation.shell_reference`: the float64 NumPy reference of the shell energies and
  forces (imported as a module: ``from bubblecal.sim.validation import shell_reference``).

Importing this package loads no Warp; the checks import it when they run.
"""

from bubblecal.sim.validation.checks import ALL_SHELL_CHECKS
from bubblecal.sim.validation.fluid_checks import ALL_FLUID_CHECKS, block_mean_sem
from bubblecal.sim.validation.reissner import measure_kantor_kappa, reissner_point_load
from bubblecal.sim.validation.result import CheckResult
from bubblecal.sim.validation.verify import all_checks, render_table, run_checks, summary_json

__all__ = ["CheckResult", "run_checks", "all_checks", "render_table", "summary_json", "ALL_SHELL_CHECKS",
           "ALL_FLUID_CHECKS", "measure_kantor_kappa", "reissner_point_load", "block_mean_sem"]
