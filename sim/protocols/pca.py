"""PCA of shell-vertex trajectories: the breathing mode and its natural frequency.

Given vertex positions ``x [T, Nv, 3]`` sampled uniformly in time (e.g. ``RingdownBatch.vertices[r]``):

1. remove the centre of mass of every frame and, optionally (``align=True``), the rigid rotation
   (Kabsch fit of each frame onto the mean frame);
2. principal components of the displacements from the mean shape [T, 3 Nv] (eigen-decomposition of
   the smaller Gram / covariance matrix);
3. the **breathing mode** is the component (among the first ``n_components``) whose spatial pattern is
   closest to a uniform radial one: the largest |cos| between the component [Nv, 3] and the unit
   radial field r_hat_v of the mean shape (``radial_overlap`` in [0, 1]; 1 = pure uniform breathing);
4. its principal coordinate a(t) -> Hann-windowed, zero-padded periodogram -> peak frequency with
   parabolic refinement.  Resolution: the Rayleigh limit ``df = 1 / (T_span)`` (DPD 1/time).
   Damping from the peak's half width at half maximum of the power, corrected for the Hann window's own
   half width (~ 0.72 / T_span), lam = 2 pi sqrt(hwhm^2 - hwhm_window^2) (0 when unresolved); natural
   frequency f_0 = sqrt(f_peak^2 + (lam / 2 pi)^2) -- for a free decay the peak sits at the damped
   frequency f_d = sqrt(f_0^2 - (lam / 2 pi)^2).

Frequencies are in cycles per unit of the ``t`` given (DPD time in the simulator).  Pure NumPy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BreathingModePCA", "breathing_mode_pca", "remove_rigid_motion", "spectral_peak"]

#: Half width at half maximum of the Hann window's power main lobe, in units of 1 / T_span.
HANN_HWHM = 0.72


@dataclass
class BreathingModePCA:
    """Result of :func:`breathing_mode_pca` (frequencies in cycles per time unit of ``t``).

    Parameters
    ----------
    f_peak : float
        Spectral peak of the breathing coordinate.
    f_0 : float
        Natural-frequency estimate.
    lam : float
        Damping rate (1 / time unit of ``t``; 0 if unresolved).
    resolution : float
        1 / T_span.
    component : int
        Index of the breathing component.
    radial_overlap : float
        Its abs(cos) with the uniform radial field, in [0, 1].
    explained_variance : numpy.ndarray
        Fraction of the displacement variance per component (first ``n_components``).
    overlaps : numpy.ndarray
        abs(cos) of each of them with the radial field.
    coordinate : numpy.ndarray
        [T] the breathing principal coordinate (positive = expansion; length unit of ``x``).
    pattern : numpy.ndarray
        [Nv, 3] the unit component.
    t : numpy.ndarray
        [T] the sample times.
    info : dict
        ``hwhm``, ``hwhm_window``, ``n_frames``, ``n_vertices``, ``aligned``.
    """

    f_peak: float
    f_0: float
    lam: float
    resolution: float
    component: int
    radial_overlap: float
    explained_variance: np.ndarray
    overlaps: np.ndarray
    coordinate: np.ndarray
    pattern: np.ndarray
    t: np.ndarray
    info: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """Scalars and short arrays (JSON-ready)."""
        return {"f_peak": self.f_peak, "f_0": self.f_0, "lam": self.lam, "resolution": self.resolution,
                "component": self.component, "radial_overlap": self.radial_overlap,
                "explained_variance": self.explained_variance.tolist(), "overlaps": self.overlaps.tolist(),
                **self.info}


def remove_rigid_motion(x: np.ndarray, align: bool = True) -> np.ndarray:
    """Remove each frame's centroid and, optionally, its rigid rotation.

    Kabsch: for each frame the proper rotation minimising sum |R y_v - m_v|^2 onto the mean centred
    frame m (two passes: the mean is recomputed after the first alignment).

    Parameters
    ----------
    x : numpy.ndarray
        Frames [T, Nv, 3] (any length unit, e.g. DPD length).
    align : bool
        Also rotate every frame onto the mean frame.

    Returns
    -------
    numpy.ndarray
        The centred (and aligned) frames [T, Nv, 3].

    Raises
    ------
    ValueError
        If ``x`` is not [T, Nv, 3].
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3:
        raise ValueError(f"vertex trajectory must have shape [T, Nv, 3], got {x.shape}")
    y = x - x.mean(axis=1, keepdims=True)
    if not align:
        return y
    for _ in range(2):
        m = y.mean(axis=0)
        h = np.einsum("tvi,vj->tij", y, m)  # [T, 3, 3] covariance y^T m
        u, _, vt = np.linalg.svd(h)
        d = np.sign(np.linalg.det(np.einsum("tij,tjk->tik", u, vt)))
        dm = np.zeros_like(h)
        dm[:, 0, 0] = 1.0
        dm[:, 1, 1] = 1.0
        dm[:, 2, 2] = d
        rot = np.einsum("tij,tjk,tkl->til", u, dm, vt)  # y_frame @ rot ~ m
        y = np.einsum("tvi,tij->tvj", y, rot)
    return y


def spectral_peak(t: np.ndarray, a: np.ndarray, pad: int = 8) -> dict[str, float]:
    """Peak of the Hann-windowed, zero-padded power spectrum of a uniformly sampled signal.

    Parameters
    ----------
    t : numpy.ndarray
        [n >= 8] strictly increasing, uniform sample times (e.g. DPD time).
    a : numpy.ndarray
        [n] the signal.
    pad : int
        Zero padding: the FFT length is the power of two >= ``pad`` n.

    Returns
    -------
    dict
        ``f_peak`` (parabolic refinement on log power), ``hwhm`` (half width at half maximum of the power
        around the peak, interpolated; NaN if not crossed), ``resolution`` = 1 / T_span and ``bin`` (the FFT
        bin width), in cycles per time unit of ``t``.

    Raises
    ------
    ValueError
        If ``t`` and ``a`` are not 1-D of equal length >= 8, or ``t`` is not uniform and increasing.
    """
    t = np.asarray(t, dtype=np.float64)
    a = np.asarray(a, dtype=np.float64)
    if t.ndim != 1 or t.shape != a.shape or t.size < 8:
        raise ValueError(f"t and the signal must be 1-D of equal length >= 8, got {t.shape}, {a.shape}")
    dts = np.diff(t)
    if np.any(dts <= 0) or np.ptp(dts) > 1e-6 * dts.mean() + 1e-12:
        raise ValueError("t must be strictly increasing and uniformly sampled")
    n = t.size
    dt = float(dts.mean())
    span = n * dt
    nfft = 1 << int(math.ceil(math.log2(pad * n)))
    power = np.abs(np.fft.rfft((a - a.mean()) * np.hanning(n), nfft)) ** 2
    freqs = np.fft.rfftfreq(nfft, dt)
    k = int(np.argmax(power[1:])) + 1
    kf = float(k)
    if 1 <= k < power.size - 1:
        la, lb, lc = np.log(power[k - 1:k + 2] + 1e-300)
        den = la - 2 * lb + lc
        if den != 0:
            kf = k + float(np.clip(0.5 * (la - lc) / den, -0.5, 0.5))
    df = float(freqs[1] - freqs[0])
    half = power[k] / 2.0

    def crossing(direction: int) -> float:
        j = k
        while 0 < j < power.size - 1 and power[j] > half:
            j += direction
        if power[j] > half:
            return float("nan")
        j0 = j - direction  # last index above half
        p0, p1 = power[j0], power[j]
        frac = (p0 - half) / (p0 - p1) if p0 != p1 else 0.0
        return abs((j0 + direction * frac) - k) * df

    hw = [crossing(-1), crossing(+1)]
    hwhm = float(np.nanmean(hw)) if np.any(np.isfinite(hw)) else float("nan")
    return {"f_peak": kf * df, "hwhm": hwhm, "resolution": 1.0 / span, "bin": df}


def breathing_mode_pca(x: np.ndarray, t: np.ndarray, *, n_components: int = 10, align: bool = True,
                       pad: int = 8) -> BreathingModePCA:
    """Breathing mode of a vertex trajectory and its frequency (module docstring for the steps).

    Parameters
    ----------
    x : numpy.ndarray
        Vertex positions [T, Nv, 3] (DPD length), sampled uniformly in time.
    t : numpy.ndarray
        [T] sample times (DPD time).
    n_components : int
        Principal components searched for the breathing mode.
    align : bool
        Remove the rigid rotation of every frame (:func:`remove_rigid_motion`).
    pad : int
        Zero padding of the spectrum (:func:`spectral_peak`).

    Returns
    -------
    BreathingModePCA
        Frequencies in cycles per DPD time.

    Raises
    ------
    ValueError
        If the shapes disagree or there are fewer than 8 frames.
    """
    t = np.asarray(t, dtype=np.float64)
    y = remove_rigid_motion(x, align=align)
    T, nv, _ = y.shape
    if t.shape != (T,):
        raise ValueError(f"t must have shape ({T},), got {t.shape}")
    if T < 8:
        raise ValueError(f"need at least 8 frames for a spectrum, got {T}")
    mean = y.mean(axis=0)
    disp = (y - mean).reshape(T, 3 * nv)
    # principal axes from the smaller Gram matrix (eigh is cheaper than an SVD of the tall matrix)
    if T <= 3 * nv:
        evals, evecs = np.linalg.eigh(disp @ disp.T)
        order = np.argsort(evals)[::-1]
        var = np.clip(evals[order], 0.0, None)
        keep = int(min(n_components, np.count_nonzero(var > var[0] * 1e-12))) if var[0] > 0 else 1
        vt = (evecs[:, order[:keep]].T @ disp) / np.sqrt(np.maximum(var[:keep], 1e-300))[:, None]
    else:
        evals, evecs = np.linalg.eigh(disp.T @ disp)
        order = np.argsort(evals)[::-1]
        var = np.clip(evals[order], 0.0, None)
        vt = evecs[:, order[:n_components]].T
    nc = int(min(n_components, vt.shape[0]))
    explained = var[:nc] / var.sum() if var.sum() > 0 else np.zeros(nc)
    rhat = mean / np.linalg.norm(mean, axis=1, keepdims=True)
    rflat = rhat.reshape(-1) / math.sqrt(nv)
    overlaps = np.abs(vt[:nc] @ rflat)  # both unit vectors
    kbest = int(np.argmax(overlaps))
    pattern = vt[kbest].copy()
    if pattern @ rflat < 0:
        pattern = -pattern
    coord = disp @ pattern
    peak = spectral_peak(t, coord, pad=pad)
    span = 1.0 / peak["resolution"]
    hw_win = HANN_HWHM / span
    hwhm = peak["hwhm"]
    lam = 2 * math.pi * math.sqrt(hwhm**2 - hw_win**2) if (math.isfinite(hwhm) and hwhm > hw_win) else 0.0
    f0 = math.sqrt(peak["f_peak"] ** 2 + (lam / (2 * math.pi)) ** 2)
    return BreathingModePCA(f_peak=peak["f_peak"], f_0=f0, lam=lam, resolution=peak["resolution"], component=kbest,
                            radial_overlap=float(overlaps[kbest]), explained_variance=explained, overlaps=overlaps,
                            coordinate=coord, pattern=pattern.reshape(nv, 3), t=t,
                            info={"hwhm": hwhm, "hwhm_window": hw_win, "n_frames": T, "n_vertices": nv,
                                  "aligned": bool(align)})
