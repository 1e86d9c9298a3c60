"""Adam steps over one epoch's batches for :func:`bubblecal.surrogates.training.train_mlp`. Imports torch.

Two interchangeable steppers with the same interface (``set_lr(lr)``, ``epoch(order) -> mean training MSE``):
:class:`EagerSteps` (CPU, or CUDA without graphs) and :class:`GraphSteps` (CUDA: each Adam step - gather,
forward, MSE, backward, update - captured once in a CUDA graph per batch size and replayed, because small MLPs
are bound by kernel-launch latency on a GPU; the learning rate lives in a device tensor so that the plateau
schedule needs no re-capture). Internal to training; not part of the curated API.
"""

from __future__ import annotations

from bubblecal._extras import require

torch = require("torch", "train")
nn = torch.nn

__all__ = ["EagerSteps", "GraphSteps", "batch_loss"]


def batch_loss(mse, pred, target, w):
    """The batch loss: the plain MSE, or the mean of the weighted squared errors with per-point weights ``w``."""
    return mse(pred, target) if w is None else torch.mean(w * (pred - target) ** 2)


class EagerSteps:
    """Plain Adam steps over one epoch's batches (CPU, or CUDA without graphs).

    Parameters
    ----------
    model : torch.nn.Module
        The network being trained.
    z, t : torch.Tensor
        Standardised training inputs (n, 7) and targets (n, 1), on the training device.
    bs : int
        Batch size.
    lr : float
        Initial learning rate.
    w : torch.Tensor, optional
        Per-point loss weights (n, 1) (:mod:`bubblecal.surrogates.training.weights`); None: the plain MSE.
    """

    def __init__(self, model: nn.Module, z: torch.Tensor, t: torch.Tensor, bs: int, lr: float,
                 w: torch.Tensor | None = None):
        self.model, self.z, self.t, self.bs, self.w = model, z, t, bs, w
        self.opt = torch.optim.Adam(model.parameters(), lr=lr)
        self.loss_fn = nn.MSELoss()

    def set_lr(self, lr: float) -> None:
        """Set the learning rate of the following steps."""
        for g in self.opt.param_groups:
            g["lr"] = lr

    def epoch(self, order: torch.Tensor) -> float:
        """One pass over the batches in ``order``; returns the mean training MSE (standardised)."""
        order = order.to(self.z.device)
        n = self.z.shape[0]
        total = 0.0
        for start in range(0, n, self.bs):
            idx = order[start:start + self.bs]
            self.opt.zero_grad(set_to_none=True)
            w = None if self.w is None else self.w[idx]
            loss = batch_loss(self.loss_fn, self.model(self.z[idx]), self.t[idx], w)
            loss.backward()
            self.opt.step()
            total += loss.item() * idx.shape[0]
        return total / n


class GraphSteps:
    """Adam steps replayed from CUDA graphs: one graph per batch size (full batches, remainder).

    Parameters
    ----------
    model : torch.nn.Module
        The network being trained (on a CUDA device).
    z, t : torch.Tensor
        Standardised training inputs (n, 7) and targets (n, 1), on the same device.
    bs : int
        Batch size.
    lr : float
        Initial learning rate.
    w : torch.Tensor, optional
        Per-point loss weights (n, 1) on the same device; None: the plain MSE.
    """

    def __init__(self, model: nn.Module, z: torch.Tensor, t: torch.Tensor, bs: int, lr: float,
                 w: torch.Tensor | None = None):
        self.model, self.z, self.t, self.bs, self.w = model, z, t, bs, w
        self.n = int(z.shape[0])
        dev = z.device
        self.params = list(model.parameters())
        self.lr = torch.tensor(float(lr), device=dev)  # a tensor: the plateau schedule needs no re-capture
        self.opt = torch.optim.Adam(self.params, lr=self.lr, capturable=True)
        self.loss_fn = nn.MSELoss()
        self.total = torch.zeros((), device=dev)
        sizes = sorted({bs, self.n % bs} - {0})
        self.idx = {m: torch.zeros(m, dtype=torch.long, device=dev) for m in sizes}
        self._warm_up(sizes, dev)
        self.graphs, self._keep = {}, []
        for m in sizes:
            g = torch.cuda.CUDAGraph()
            self.opt.zero_grad(set_to_none=True)  # each graph owns its gradient buffers
            with torch.cuda.graph(g):
                self._step(m)
            self._keep.append([p.grad for p in self.params])  # keep the captured buffers alive
            self.graphs[m] = g

    def _step(self, m: int) -> None:
        idx = self.idx[m]
        loss = batch_loss(self.loss_fn, self.model(self.z[idx]), self.t[idx], None if self.w is None else self.w[idx])
        loss.backward()
        self.opt.step()
        self.total.add_(loss.detach() * m)

    def _warm_up(self, sizes, dev) -> None:
        # capture needs warmed-up kernels and existing optimizer state; undo the warm-up steps afterwards
        saved = [p.detach().clone() for p in self.params]
        side = torch.cuda.Stream(device=dev)
        side.wait_stream(torch.cuda.current_stream(dev))
        with torch.cuda.stream(side):
            for m in sizes:
                for _ in range(3):
                    self.opt.zero_grad(set_to_none=True)
                    self._step(m)
        torch.cuda.current_stream(dev).wait_stream(side)
        with torch.no_grad():
            for p, v in zip(self.params, saved, strict=True):
                p.copy_(v)
            for st in self.opt.state.values():
                for v in st.values():
                    if torch.is_tensor(v):
                        v.zero_()  # step = 0, exp_avg = exp_avg_sq = 0: a fresh Adam
            self.total.zero_()

    def set_lr(self, lr: float) -> None:
        """Set the learning rate of the following steps (in the device tensor the graphs read)."""
        self.lr.fill_(float(lr))

    def epoch(self, order: torch.Tensor) -> float:
        """One pass over the batches in ``order``; returns the mean training MSE (standardised)."""
        order = order.to(self.z.device)
        self.total.zero_()
        for start in range(0, self.n, self.bs):
            m = min(self.bs, self.n - start)
            self.idx[m].copy_(order[start:start + m])
            self.graphs[m].replay()
        return float(self.total) / self.n
