"""PyTorch training of one standardised tanh MLP surrogate (CPU, or CUDA for sweeps). Imports torch.

The recipe: tanh hidden layers, Xavier-uniform weights and zero biases; inputs ``(ka, kb, b1, b2, a3, a4, x)``
and the target standardised with the training points' mean and standard deviation (stored with the weights);
a seeded 90/10 *pointwise* split of the training points for monitoring; Adam on the MSE of the standardised
target; the learning rate is divided by 10 when the validation loss has not improved by a relative
``min_rel_improvement`` for ``patience`` epochs; training stops when it stalls again after ``max_reductions``
reductions, or at ``max_epochs``. The weights with the best validation loss are returned. Same seed, same
data and same thread count give bit-identical weights.

``device = "cuda"`` trains the same recipe on a GPU: the initial weights and the batch order are drawn from
the same CPU generator (identical to the CPU run); only floating-point rounding differs. By default each Adam
step is replayed from a CUDA graph (``cuda_graphs``, :mod:`bubblecal.surrogates.training.steps`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from bubblecal._extras import require
from bubblecal.surrogates.mlp import mlp_forward
from bubblecal.surrogates.training.steps import EagerSteps, GraphSteps, batch_loss
from bubblecal.surrogates.training.weights import CURVE_WEIGHTS, curve_weights

torch = require("torch", "train")
nn = torch.nn

__all__ = ["TrainConfig", "TrainedMLP", "NormalisedMLP", "train_mlp", "numpy_forward"]


@dataclass(frozen=True)
class TrainConfig:
    """Training settings of :func:`train_mlp` (module docstring).

    Parameters
    ----------
    lr : float
        Initial Adam learning rate.
    batch_size : int
        Training points per Adam step.
    max_epochs : int
        Most epochs.
    patience : int
        Epochs without relative improvement ``min_rel_improvement`` of the validation loss before the
        learning rate is reduced (or training stops after ``max_reductions`` reductions).
    lr_factor : float
        Learning-rate reduction factor.
    max_reductions : int
        Most learning-rate reductions.
    min_rel_improvement : float
        Relative decrease of the validation loss that counts as an improvement.
    val_frac : float
        Fraction of the training points held out (pointwise) for monitoring.
    threads : int or None
        torch intra-op threads during training (1 suits these small MLPs; None keeps torch's setting).
    device : str
        ``'cpu'``, ``'cuda'`` or ``'cuda:N'``.
    cuda_graphs : bool
        On CUDA, replay one captured graph per Adam step (launch latency dominates small MLPs).
    curve_weights : str
        How much each curve counts in the loss (:mod:`bubblecal.surrogates.training.weights`): ``"none"`` (the
        plain MSE over points) or ``"capped"`` (a curve larger than the median one counts as much as it).

    Raises
    ------
    ValueError
        For an unknown ``device`` or ``curve_weights``.
    """

    lr: float = 1e-3
    batch_size: int = 256
    max_epochs: int = 3000
    patience: int = 40
    lr_factor: float = 0.1
    max_reductions: int = 3
    min_rel_improvement: float = 1e-4
    val_frac: float = 0.1
    threads: int | None = 1
    device: str = "cpu"
    cuda_graphs: bool = True
    curve_weights: str = "none"

    def __post_init__(self):
        dev = str(self.device)
        if dev != "cpu" and dev != "cuda" and not (dev.startswith("cuda:") and dev[5:].isdigit()):
            raise ValueError(f"TrainConfig.device must be 'cpu', 'cuda' or 'cuda:N', got {self.device!r}")
        if self.curve_weights not in CURVE_WEIGHTS:
            raise ValueError(f"TrainConfig.curve_weights must be one of {CURVE_WEIGHTS}, got {self.curve_weights!r}")

    def as_dict(self) -> dict:
        """The settings as a plain dict (recorded in metadata and checkpoints; ``curve_weights`` only when not
        ``"none"``, so the recipes of earlier networks and their checkpoint keys read unchanged)."""
        d = asdict(self)
        if d["curve_weights"] == "none":
            del d["curve_weights"]
        return d


def numpy_forward(weights, biases, in_mean, in_std, out_mean, out_std, u) -> np.ndarray:
    """float64 numpy evaluation of :func:`bubblecal.surrogates.mlp.mlp_forward`.

    Parameters
    ----------
    weights, biases : sequence of array_like
        Layer weights (fan_in, fan_out) and biases (fan_out,).
    in_mean, in_std, out_mean, out_std : array_like
        Standardisation of the raw inputs and outputs.
    u : array_like, shape (..., n_in)
        Raw inputs (ka, kb, b1, b2, a3, a4, x) [DPD units].

    Returns
    -------
    numpy.ndarray, shape (..., n_out)
        Raw outputs [DPD force or DPD length].
    """
    return mlp_forward([np.asarray(w, dtype=float) for w in weights], [np.asarray(b, dtype=float) for b in biases],
                       in_mean, in_std, out_mean, out_std, np.asarray(u, dtype=float), xp=np)


class NormalisedMLP(nn.Module):
    """Raw inputs (n, 7) -> raw outputs (n, 1): standardise, tanh MLP, de-standardise (the ONNX export's module).

    Parameters
    ----------
    layer_sizes : sequence of int
        Widths from the input to the output layer.
    in_mean, in_std : array_like, shape (n_in,)
        Standardisation of the raw inputs (DPD units).
    out_mean, out_std : array_like, shape (n_out,)
        Standardisation of the raw output.
    """

    def __init__(self, layer_sizes: Sequence[int], in_mean, in_std, out_mean, out_std):
        super().__init__()
        self.layers = nn.ModuleList(nn.Linear(a, b) for a, b in zip(layer_sizes[:-1], layer_sizes[1:], strict=True))
        self.register_buffer("in_mean", torch.as_tensor(np.asarray(in_mean), dtype=torch.float32))
        self.register_buffer("in_std", torch.as_tensor(np.asarray(in_std), dtype=torch.float32))
        self.register_buffer("out_mean", torch.as_tensor(np.atleast_1d(out_mean), dtype=torch.float32))
        self.register_buffer("out_std", torch.as_tensor(np.atleast_1d(out_std), dtype=torch.float32))

    def forward(self, u):
        """Raw outputs (n, 1) of raw inputs ``u`` (n, 7)."""
        h = (u - self.in_mean) / self.in_std
        for i, layer in enumerate(self.layers):
            h = layer(h)
            if i < len(self.layers) - 1:
                h = torch.tanh(h)
        return h * self.out_std + self.out_mean


@dataclass
class TrainedMLP:
    """Result of :func:`train_mlp`: plain numpy weights, standardisation statistics and the training history.

    Parameters
    ----------
    hidden : tuple of int
        Hidden-layer widths.
    weights, biases : list of numpy.ndarray
        Layer weights (fan_in, fan_out) (the transpose of torch's ``Linear.weight``) and biases (fan_out,).
    in_mean, in_std : numpy.ndarray, shape (7,)
        Mean and standard deviation of the raw training inputs (DPD units).
    out_mean, out_std : numpy.ndarray, shape (1,)
        Mean and standard deviation of the raw training target.
    config : TrainConfig
        The settings used.
    seed : int
        Seed of the split, the initial weights and the batch order.
    epochs : int
        Epochs run.
    stop_reason : str
        Why training stopped (``'max_epochs'``, a plateau, a non-finite validation loss).
    best_val_loss : float
        Best validation MSE (standardised target).
    wall_s : float
        Training wall time [s].
    history : dict
        Per-epoch ``train_loss``, ``val_loss`` and ``lr``.
    """

    hidden: tuple[int, ...]
    weights: list[np.ndarray]
    biases: list[np.ndarray]
    in_mean: np.ndarray
    in_std: np.ndarray
    out_mean: np.ndarray
    out_std: np.ndarray
    config: TrainConfig
    seed: int
    epochs: int
    stop_reason: str
    best_val_loss: float
    wall_s: float
    history: dict = field(default_factory=dict)

    @property
    def layer_sizes(self) -> list[int]:
        """Widths from the input to the output layer."""
        return [self.weights[0].shape[0]] + [w.shape[1] for w in self.weights]

    def predict(self, u) -> np.ndarray:
        """Raw outputs in float64 numpy.

        Parameters
        ----------
        u : array_like, shape (n, 7)
            Raw inputs (ka, kb, b1, b2, a3, a4, x) [DPD units].

        Returns
        -------
        numpy.ndarray, shape (n,)
            Raw outputs [DPD force (compression) or DPD length (indentation)].
        """
        return numpy_forward(self.weights, self.biases, self.in_mean, self.in_std, self.out_mean,
                             self.out_std, u)[..., 0]

    def torch_module(self, dtype=torch.float32) -> NormalisedMLP:
        """A torch module with these weights and the standardisation built in (evaluation mode).

        Parameters
        ----------
        dtype : torch.dtype
            Parameter dtype of the module.

        Returns
        -------
        NormalisedMLP
            Raw inputs (n, 7) -> raw outputs (n, 1).
        """
        mod = NormalisedMLP(self.layer_sizes, self.in_mean, self.in_std, self.out_mean, self.out_std)
        with torch.no_grad():
            for layer, w, b in zip(mod.layers, self.weights, self.biases, strict=True):
                layer.weight.copy_(torch.as_tensor(w.T.copy()))
                layer.bias.copy_(torch.as_tensor(b))
        return mod.to(dtype).eval()

    def training_summary(self) -> dict:
        """Architecture, seed, epochs, stop reason, best loss, wall time and settings (the metadata's ``training``)."""
        return {"hidden": list(self.hidden), "seed": self.seed, "epochs": self.epochs,
                "stop_reason": self.stop_reason, "best_val_loss": self.best_val_loss, "wall_s": self.wall_s,
                "config": self.config.as_dict()}


def _build(layer_sizes: Sequence[int], gen: torch.Generator) -> nn.Sequential:
    """The tanh MLP with Xavier-uniform weights (from ``gen``) and zero biases."""
    mods: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(layer_sizes[:-1], layer_sizes[1:], strict=True)):
        lin = nn.Linear(a, b)
        nn.init.xavier_uniform_(lin.weight, generator=gen)
        nn.init.zeros_(lin.bias)
        mods.append(lin)
        if i < len(layer_sizes) - 2:
            mods.append(nn.Tanh())
    return nn.Sequential(*mods)


def train_mlp(u: np.ndarray, y: np.ndarray, hidden: Sequence[int], config: TrainConfig | None = None,
              seed: int = 0, progress: bool = True, desc: str = "train", curve: np.ndarray | None = None) -> TrainedMLP:
    """Train one MLP with the recipe of the module docstring.

    Parameters
    ----------
    u : numpy.ndarray, shape (n, 7)
        Raw inputs (ka, kb, b1, b2, a3, a4, x) [DPD units].
    y : numpy.ndarray, shape (n,)
        Raw targets [DPD force (compression) or DPD length (indentation)].
    hidden : sequence of int
        Hidden-layer widths.
    config : TrainConfig, optional
        Settings (default ``TrainConfig()``).
    seed : int
        Seed of the validation split (numpy), the initial weights and the batch order (torch).
    progress : bool
        Show a progress bar.
    desc : str
        Label of the progress bar.
    curve : numpy.ndarray of int, shape (n,), optional
        Curve index of each point; needed by ``config.curve_weights`` other than ``"none"``.

    Returns
    -------
    TrainedMLP
        The weights with the best validation loss (the weighted one with curve weights).

    Raises
    ------
    ValueError
        For mismatched shapes, fewer than 10 points, an input column or target of zero variance, or curve weights
        without ``curve``.
    """
    from bubblecal._progress import ProgressLine

    config = config or TrainConfig()
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float).reshape(-1)
    if u.ndim != 2 or u.shape[0] != y.shape[0]:
        raise ValueError(f"u must be (n, n_in) and y (n,), got {u.shape} and {y.shape}")
    if u.shape[0] < 10:
        raise ValueError(f"too few training points ({u.shape[0]})")
    old_threads = torch.get_num_threads()
    if config.threads:
        torch.set_num_threads(int(config.threads))
    t0 = time.perf_counter()
    try:
        rng = np.random.default_rng(seed)
        perm = rng.permutation(u.shape[0])
        n_val = max(1, int(round(config.val_frac * u.shape[0])))
        val_idx, tr_idx = perm[:n_val], perm[n_val:]
        in_mean = u[tr_idx].mean(axis=0)
        in_std = u[tr_idx].std(axis=0)
        out_mean = np.array([y[tr_idx].mean()])
        out_std = np.array([y[tr_idx].std()])
        zero = np.flatnonzero(in_std <= 0)
        if zero.size:
            raise ValueError(f"input column(s) {zero.tolist()} have zero variance in the training points")
        if out_std[0] <= 0:
            raise ValueError("target has zero variance in the training points")
        z = torch.as_tensor((u - in_mean) / in_std, dtype=torch.float32)
        t = torch.as_tensor(((y - out_mean[0]) / out_std[0])[:, None], dtype=torch.float32)
        z_tr, t_tr = z[tr_idx], t[tr_idx]
        z_va, t_va = z[val_idx], t[val_idx]
        if config.curve_weights != "none" and curve is None:
            raise ValueError(f"curve_weights {config.curve_weights!r} needs the curve index of each point (curve)")
        w = curve_weights(y, curve, config.curve_weights) if curve is not None else None
        w = None if w is None else torch.as_tensor(w[:, None], dtype=torch.float32)
        w_tr, w_va = (None, None) if w is None else (w[tr_idx], w[val_idx])

        gen = torch.Generator().manual_seed(int(seed))
        sizes = [u.shape[1], *[int(h) for h in hidden], 1]
        model = _build(sizes, gen)
        dev = torch.device(config.device)
        if dev.type == "cuda":
            model = model.to(dev)
            z_tr, t_tr, z_va, t_va = (x.to(dev) for x in (z_tr, t_tr, z_va, t_va))
            w_tr, w_va = (None, None) if w is None else (w_tr.to(dev), w_va.to(dev))
        mse = nn.MSELoss()
        lr = config.lr
        n_tr = z_tr.shape[0]
        bs = min(config.batch_size, n_tr)
        if dev.type == "cuda" and config.cuda_graphs:
            stepper = GraphSteps(model, z_tr, t_tr, bs, lr, w=w_tr)
        else:
            stepper = EagerSteps(model, z_tr, t_tr, bs, lr, w=w_tr)
        best = math.inf
        best_state = {k: v.clone() for k, v in model.state_dict().items()}
        wait = 0
        reductions = 0
        stop_reason = "max_epochs"
        hist_train, hist_val, hist_lr = [], [], []
        with ProgressLine(desc or "train", total=config.max_epochs, enabled=progress) as bar:
            epoch = 0
            for epoch in range(config.max_epochs):
                model.train()
                # the batch order comes from the CPU generator on every device (same order as a CPU run)
                order = torch.randperm(n_tr, generator=gen)
                hist_train.append(stepper.epoch(order))
                model.eval()
                with torch.no_grad():
                    val = float(batch_loss(mse, model(z_va), t_va, w_va))
                hist_val.append(val)
                hist_lr.append(lr)
                if not math.isfinite(val):
                    stop_reason = "non-finite validation loss"
                    break
                if val < best * (1.0 - config.min_rel_improvement):
                    best = val
                    best_state = {k: v.clone() for k, v in model.state_dict().items()}
                    wait = 0
                else:
                    wait += 1
                    if wait >= config.patience:
                        if reductions >= config.max_reductions:
                            stop_reason = f"plateau after {reductions} lr reductions"
                            break
                        reductions += 1
                        lr *= config.lr_factor
                        stepper.set_lr(lr)
                        wait = 0
                info = f"train {hist_train[-1]:.3g} val {val:.3g} lr {lr:.0e}" if epoch % 10 == 0 else None
                bar.update(advance=1, info=info)
        model.load_state_dict(best_state)
        linears = [m for m in model if isinstance(m, nn.Linear)]
        weights = [m.weight.detach().cpu().numpy().T.copy() for m in linears]
        biases = [m.bias.detach().cpu().numpy().copy() for m in linears]
    finally:
        if config.threads:
            torch.set_num_threads(old_threads)
    return TrainedMLP(hidden=tuple(int(h) for h in hidden), weights=weights, biases=biases, in_mean=in_mean,
                      in_std=in_std, out_mean=out_mean, out_std=out_std, config=config, seed=int(seed),
                      epochs=epoch + 1, stop_reason=stop_reason, best_val_loss=float(best),
                      wall_s=time.perf_counter() - t0,
                      history={"train_loss": hist_train, "val_loss": hist_val, "lr": hist_lr})
