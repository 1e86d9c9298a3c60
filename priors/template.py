"""An editable priors file for a user's agent, started from the shipped priors of its protocol's published agent.

A user's agent measured by compression starts from Definity's ranges, one measured by indentation from
SonoVue's (:data:`~bubblecal.data.PUBLISHED_AGENT_OF_PROTOCOL`). The ``[workflow]`` agent stays the published
one, since it names the surrogates and acoustic laws the ranges refer to; the user's label goes into
``description``.
"""

from __future__ import annotations

import json

from bubblecal.data import LOADING_PROTOCOLS, PUBLISHED_AGENT_OF_PROTOCOL
from bubblecal.priors.loading import PriorError, prior_path, workflow_file_name

__all__ = ["priors_template"]

_HEADER = """\
# bubblecal priors for agent {label} (protocol: {protocol}), an editable copy of the shipped priors of the
# published {protocol} agent ({published}, file {shipped}.toml). Edit the ranges below for your bubbles.
#
# What a range means (units are DPD units, see the unit lines below):
#   prior     = [lo, hi]  every value one bubble's parameter may take (uniform); lo < hi
#   hyper_m   = [lo, hi]  where the population mean m of the agent may lie (inside the prior)
#   hyper_tau = [lo, hi]  how far the bubbles of the agent may spread around m (0 <= lo < hi)
# [workflow] agent names the published agent whose surrogates and acoustic laws serve this protocol; keep it.
# Check the file with:  bubblecal priors check THIS_FILE
#
"""


def priors_template(label: str, protocol: str, workflow: str = "reduced") -> str:
    """The text of an editable priors TOML for agent ``label``.

    Parameters
    ----------
    label : str
        The user's agent label (any non-empty text without line breaks).
    protocol : str
        'compression' or 'indentation': picks the published agent whose shipped priors are copied.
    workflow : str
        'full', 'reduced' or 'reduced-acoustic'.

    Returns
    -------
    str
        A TOML file that :func:`~bubblecal.priors.load_priors` accepts: the shipped file's ranges and comments
        under a header naming ``label``, with ``description`` set to the label.

    Raises
    ------
    PriorError
        An empty label or one with line breaks, an unknown protocol or workflow.
    """
    problems = []
    if not label.strip() or any(c in label for c in "\r\n"):
        problems.append(f"agent label {label!r}: must be non-empty text on one line")
    if protocol not in LOADING_PROTOCOLS:
        problems.append(f"protocol {protocol!r}: allowed {', '.join(LOADING_PROTOCOLS)}")
    if problems:
        raise PriorError("priors template", problems)
    published = PUBLISHED_AGENT_OF_PROTOCOL[protocol]
    shipped = workflow_file_name(published, workflow)
    try:
        text = prior_path(shipped).read_text(encoding="utf-8")
    except PriorError as exc:
        raise PriorError("priors template", [f"workflow {workflow!r}: no shipped file {shipped}.toml"]) from exc
    description = json.dumps(f"{label.strip()}: {protocol}, starting from the shipped {shipped} priors",
                             ensure_ascii=True)
    lines, out = text.splitlines(), []
    for line in lines:
        if line.strip().startswith("description"):
            continue
        out.append(line)
        if line.strip() == "[workflow]":
            out.append(f"description = {description}")
    head = _HEADER.format(label=json.dumps(label.strip(), ensure_ascii=False), protocol=protocol,
                          published=published, shipped=shipped)
    return head + "\n".join(out) + "\n"
