"""ChunkGraph: every requested step runs exactly once, whether warmed up, captured, replayed or plain."""

from __future__ import annotations

import pytest

pytest.importorskip("warp")

from bubblecal.sim.engine import graphs  # noqa: E402


class FakeCuda:
    """Stands in for CUDA stream capture: launches inside a capture are recorded, not executed."""

    def __init__(self):
        self.executed = 0
        self.recorded = 0
        self.capturing = False
        self.captures = 0

    def step(self):
        if self.capturing:
            self.recorded += 1
        else:
            self.executed += 1

    def scoped_capture(self, device=None, force_module_load=False):
        fake = self

        class Capture:
            def __enter__(self):
                fake.capturing, fake.recorded = True, 0
                fake.captures += 1
                return self

            def __exit__(self, *exc):
                fake.capturing = False
                self.graph = fake.recorded
                return False

        return Capture()

    def capture_launch(self, graph):
        self.executed += graph


@pytest.fixture
def fake(monkeypatch):
    f = FakeCuda()
    monkeypatch.setattr(graphs.wp, "ScopedCapture", f.scoped_capture)
    monkeypatch.setattr(graphs.wp, "capture_launch", f.capture_launch)
    return f


def test_capture_then_replay_runs_every_step_once(fake):
    g = graphs.ChunkGraph(fake.step, "cuda:0", enabled=True)
    for _ in range(5):
        g.run(10)
    g.run(3, capture=False)  # a shorter last chunk: plain launches
    assert fake.executed == 53 and fake.captures == 1 and g.graph == 10
    g.invalidate()  # e.g. arrays reallocated: the next full chunk is captured again and still executed
    g.run(10)
    assert fake.executed == 63 and fake.captures == 2


def test_disabled_runs_plain(fake):
    g = graphs.ChunkGraph(fake.step, "cpu", enabled=False)
    g.run(7)
    assert fake.executed == 7 and fake.captures == 0 and g.graph is None
