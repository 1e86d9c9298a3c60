"""CLI tests read rich tables: give the shared consoles a wide, colourless terminal."""

import pytest

from bubblecal.workflows.console import console, err_console


@pytest.fixture(autouse=True)
def _wide_console():
    saved = [(c, c.width, c.no_color) for c in (console, err_console)]
    for c in (console, err_console):
        c.width = 220
        c.no_color = True
    yield
    for c, width, no_color in saved:
        c.width = width
        c.no_color = no_color
