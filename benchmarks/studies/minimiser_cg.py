"""Does a nonlinear conjugate gradient relax a buckled quasi-static shell with fewer force evaluations than FIRE?

A design point of the compression design over the diameter is compressed with the campaign's quasi-static settings
(thermal plate contact, ideal gas, float64, the campaign's mesh level) up to load point ``--upto`` (past the
buckle at large sizes).  From that minimum the plates move one more sub-step (``--step`` per plate, DPD length), and
the shell is relaxed twice from the same start, both to the tier's per-vertex force tolerance (0.05 DPD force):

* FIRE, exactly as the tier runs it (:class:`bubblecal.sim.engine.minimize_device.DeviceFire`);
* the Polak-Ribiere+ nonlinear CG of :func:`bubblecal.sim.engine.minimize_cg.cg_minimize` (the NumPy reference of
  the tier's ``minimizer = "cg"``), driven from the host.

The forces are the tier's own (``_DeviceChain._forces`` on one replica, the mean x, y force removed as the tier does).
Reported: force evaluations of each, the largest vertex distance between the two minima and their plate forces.

    python benchmarks/studies/minimiser_cg.py --diameter 7.0 --point 13 --upto 9 [--step 0.06]

Prints the two results and one JSON line (``{"study": "minimiser_cg", ...}``).  CPU only (a prototype: the CG's
vectors live on the host).
"""

from __future__ import annotations

import argparse
import json

import numpy as np

CAMPAIGN = "definity_compression_1.5-8um"
FTOL = 0.05


def buckled_state(diameter_um: float, point: int, upto: int):
    """The tier's minimum at load point ``upto - 1`` of one design point: (chain, x [Nv, 3], top plate z, info)."""
    from bubblecal.campaigns import design_points, load_campaign_file
    from bubblecal.data import SHELL_PARAMETERS
    from bubblecal.sim.engine.mesh import mesh_for_diameter
    from bubblecal.sim.engine.system import resolve_dtype
    from bubblecal.sim.protocols.plates import PlateContact
    from bubblecal.sim.tiers import CurveRequest, get_tier
    from bubblecal.sim.tiers.quasistatic import FireSettings, IdealGas, ThermalContact, quasistatic_compression
    from bubblecal.sim.tiers.quasistatic.backends import _DeviceChain

    cfg = load_campaign_file(CAMPAIGN).config
    design = design_points(cfg)
    idx = np.nonzero(np.isclose(design["diameter_um"], diameter_um))[0][[point]]
    tier = get_tier("quasistatic", **cfg.physics_tier_settings())
    grid = np.asarray(cfg.grid_for(diameter_um))[:upto]
    request = CurveRequest(protocol="compression", diameter_um=diameter_um, grid=tuple(grid),
                           params={k: np.asarray(design[k][idx]) for k in SHELL_PARAMETERS},
                           seeds=tuple(int(s) for s in design["seed"][idx]), subdivisions=cfg.subdivisions)
    params = request.shell_params(tier.indentation_convention)
    mesh = mesh_for_diameter(diameter_um, cfg.subdivisions)
    fire = FireSettings(ftol=FTOL, max_steps=tier.max_steps)
    gas, thermal = IdealGas(p0=tier.gas_p0), ThermalContact(kT=tier.kT)
    res = quasistatic_compression(params, mesh, grid, gas=gas, thermal=thermal, device="cpu",
                                  dtype=resolve_dtype("float64"), fire=fire)
    nv = mesh.n_vertices
    chain = _DeviceChain(params, mesh, gas, "cpu", None, fire, free_v=np.ones((nv, 3), dtype=bool),
                         remove_mean=(True, True, False), contact=PlateContact(), thermal=thermal,
                         radius_dpd=float(res.settings["thermal_contact"]["radius_dpd"]))
    info = {"ka": float(design["ka"][idx[0]]), "kb": float(design["kb"][idx[0]]), "d_dpd": float(grid[-1]),
            "force": float((res.force + res.force_bottom)[0, -1]), "fire_steps_chain": res.fire_steps[0].tolist()}
    return chain, res.x_final.copy(), float(res.plate_z[-1]), float(mesh.vertices[:, 2].mean()), info


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--diameter", type=float, default=7.0, help="diameter level of the design [um]")
    ap.add_argument("--point", type=int, default=13, help="design point of the level")
    ap.add_argument("--upto", type=int, default=9, help="load points of the grid relaxed first")
    ap.add_argument("--step", type=float, default=0.06, help="the next plate move (per plate, DPD length)")
    args = ap.parse_args(argv)
    import warp as wp

    from bubblecal.sim.engine.minimize_cg import cg_minimize

    wp.config.quiet = True
    chain, x0, plate, zc, info = buckled_state(args.diameter, args.point, args.upto)
    top = plate - args.step
    chain.set_plates(top, 2 * zc - top)

    chain.fire.set_positions(x0)
    fire = chain.fire.minimize(ftol=FTOL, max_steps=200_000)
    x_fire = chain.fire.positions()

    def force(x):
        chain.fire.status.assign(np.zeros(1, dtype=np.int32))  # ACTIVE: the kernels skip finished replicas
        chain.fire.x.assign(x)
        chain.fire.f.zero_()
        chain._forces(chain.fire.x, chain.fire.f)
        f = chain.fire.f.numpy().astype(np.float64)
        f[:, :2] -= f[:, :2].mean(axis=0)  # the tier's centre-of-mass pin in x, y
        return f

    cg = cg_minimize(force, x0, ftol=FTOL, max_steps=200_000)
    x_cg, iters, n_eval, fmax = cg.x, cg.n_lines, cg.steps + 1, cg.fmax

    def plate_force(x):
        chain.fire.x.assign(x)
        obs = chain.measure(0)
        return float(obs["top"][0] + obs["bottom"][0])

    out = {"study": "minimiser_cg", "diameter_um": args.diameter, "point": args.point, "upto": args.upto,
           "step": args.step, **info, "fire_status": fire.status[0], "fire_evaluations": int(fire.steps[0]) + 1,
           "cg_iterations": iters, "cg_evaluations": n_eval, "cg_fmax": fmax,
           "max_vertex_distance": float(np.max(np.linalg.norm(x_cg - x_fire, axis=1))),
           "plate_force_fire": plate_force(x_fire), "plate_force_cg": plate_force(x_cg)}
    print(f"FIRE: {out['fire_evaluations']} force evaluations ({out['fire_status']}); CG: {n_eval} force evaluations "
          f"in {iters} iterations (fmax {fmax:.3f}); minima {out['max_vertex_distance']:.4f} apart; plate force "
          f"{out['plate_force_fire']:.1f} / {out['plate_force_cg']:.1f}")
    print(json.dumps(out))


if __name__ == "__main__":
    main()
