"""Names defined once: parameters, agents, protocols, statuses and the code version.

Every layer imports these instead of writing its own copy, so that a parameter keeps one name from a priors
TOML through the NumPyro model to the surrogate input and the campaign record (docs/physics.md, section 1;
units in :mod:`bubblecal.data.units`).
"""

from __future__ import annotations

import subprocess
from pathlib import Path

__all__ = [
    "SHELL_PARAMETERS",
    "NONLINEAR_PARAMETERS",
    "MODEL_PARAMETERS",
    "NOISE_PARAMETERS",
    "PARAMETER_UNITS",
    "POSITIVE_PARAMETERS",
    "AGENTS",
    "LOADING_PROTOCOLS",
    "PROTOCOLS",
    "PUBLISHED_AGENT_OF_PROTOCOL",
    "STATUSES",
    "RECORD_STATUSES",
    "RETRY_STATUSES",
    "code_version",
]

#: Shell constants in surrogate input order (DPD units; the shear modulus is always mu = ka / 3).
SHELL_PARAMETERS: tuple[str, ...] = ("ka", "kb", "b1", "b2", "a3", "a4")
#: The Lim nonlinear coefficients that a reduced shell fixes to zero.
NONLINEAR_PARAMETERS: tuple[str, ...] = ("b1", "b2", "a3", "a4")
#: Parameters of one mechanical dataset: the shell constants followed by the loading offset ``d0``.
MODEL_PARAMETERS: tuple[str, ...] = SHELL_PARAMETERS + ("d0",)
#: Relative noise amplitudes: ``sigma`` (single-dataset mechanics), ``sigma_mech`` and ``sigma_ac``
#: (workflows with acoustic data).
NOISE_PARAMETERS: tuple[str, ...] = ("sigma", "sigma_mech", "sigma_ac")
#: Unit of each parameter (DPD units, docs/physics.md section 1).
PARAMETER_UNITS: dict[str, str] = {
    "ka": "DPD 2-D modulus (k_BT/r_c^2, fscale applied)", "kb": "DPD energy (k_BT, fscale applied)",
    "b1": "1", "b2": "1", "a3": "1", "a4": "1", "d0": "DPD length", "sigma": "1", "sigma_mech": "1", "sigma_ac": "1",
}
#: Parameters that must be strictly positive (the moduli).
POSITIVE_PARAMETERS: tuple[str, ...] = ("ka", "kb")

#: Contrast agents of the published study.
AGENTS: tuple[str, ...] = ("definity", "sonovue")

#: Mechanical loading protocols: compression (x = imposed displacement, y = force) and indentation
#: (x = applied pole force, y = pole-to-pole displacement).
LOADING_PROTOCOLS: tuple[str, ...] = ("compression", "indentation")
#: The published agent measured with each loading protocol: its shipped priors, surrogates and laws are the
#: starting point for a user's agent measured the same way.
PUBLISHED_AGENT_OF_PROTOCOL: dict[str, str] = {"compression": "definity", "indentation": "sonovue"}
#: Every simulated protocol: the loading protocols and the radial ringdown (x = time, y = R(t)).
PROTOCOLS: tuple[str, ...] = LOADING_PROTOCOLS + ("ringdown",)

#: Outcome of one simulated curve, reported by every tier.
STATUSES: tuple[str, ...] = ("ok", "ruptured", "failed", "unstable", "timeout")
#: Statuses a campaign record may hold: the tiers' plus ``invalid`` (reported ok, but non-finite numbers).
RECORD_STATUSES: tuple[str, ...] = STATUSES + ("invalid",)
#: Statuses a resumed campaign runs again by default.
RETRY_STATUSES: tuple[str, ...] = ("failed", "timeout")

_CODE_VERSION: str | None = None


def code_version() -> str:
    """The running code's version, for provenance records.

    Returns
    -------
    str
        The installed ``bubblecal`` version, followed by ``+g<commit>`` (and ``.dirty`` when the work tree
        has uncommitted changes) when the package is a git checkout; computed once per process.
    """
    global _CODE_VERSION
    if _CODE_VERSION is None:
        from bubblecal import __version__

        v = str(__version__)
        root = Path(__file__).resolve().parents[1]
        try:
            commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                                    text=True, timeout=5)
            if commit.returncode == 0 and commit.stdout.strip():
                v += f"+g{commit.stdout.strip()}"
                dirty = subprocess.run(["git", "-C", str(root), "diff", "--quiet", "HEAD", "--"],
                                       capture_output=True, timeout=10)
                if dirty.returncode == 1:
                    v += ".dirty"
        except (OSError, subprocess.SubprocessError):
            pass
        _CODE_VERSION = v
    return _CODE_VERSION
