"""Robot systems (docs/systems.md): forward kinematics and Jacobians of a tree against
pinocchio, and what a system costs per row against one chain.

TALOS (example-robot-data's ``talos_reduced.urdf``) with three tips: both grippers and the
head (16 + 2 joints, 249 parameters). Rows of random tips, ``N`` of them:

* **FK**: kinecal's ``SystemModel.fk`` (4x4 tool frames of each row's tip) and
  ``positions`` in one call, against pinocchio 4 (C++) as its Python users call it, a loop
  over the rows of ``forwardKinematics`` + ``updateFramePlacement`` of the row's tip frame
  (pinocchio has no batch call in Python). Both on the same configurations, best of
  interleaved rounds.
* **Joint Jacobian**: ``SystemModel.joint_jacobian`` (6 x joints per row) against
  pinocchio's ``computeFrameJacobian`` (LOCAL_WORLD_ALIGNED) per row.
* **Identification Jacobian**: ``SystemModel.jacobian_t`` of every parameter (pinocchio has
  no derivative with respect to the geometry); its cost per row and per column of the
  row's chain against one chain's (`SerialModel.jacobian_t` of the left arm alone, read
  from the same URDF).
* **Calibration per row**: ``calibrate`` of the three-chain system from ``N`` tracker rows
  against the left arm alone from ``N`` rows, as a system of one tip (the same stacked
  problem) and on the serial path of one chain (chunked normal equations).

Run: ``python benchmarks/bench_systems.py [--quick]``.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import os
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

TIPS = ["gripper_left_base_link", "gripper_right_base_link", "head_2_link"]


def talos_path() -> str:
    dist = importlib.metadata.distribution("example-robot-data")
    return str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots/"
                                "talos_data/robots/talos_reduced.urdf"))


def best(fn, rounds: int) -> float:
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def pinocchio_peer(path, system, q, tips):
    """pinocchio's model, its configurations of `q` and tip frame ids (set-up, not timed)."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(path)
    data = model.createData()
    idx = [model.joints[model.getJointId(n)].idx_q for n in system.joint_names]
    cfg = np.tile(pin.neutral(model), (len(q), 1))
    cfg[:, idx] = q
    frames = [model.getFrameId(t) for t in system.tips]
    fid = [frames[t] for t in tips]
    return pin, model, data, cfg, fid


def kinematics(n: int, rounds: int) -> dict:
    from kinecal.io.urdf_tree import load_urdf_system

    path = talos_path()
    system = load_urdf_system(path, TIPS)
    rng = np.random.default_rng(0)
    lo, hi = system.joint_limits[:, 0], system.joint_limits[:, 1]
    q = rng.uniform(lo, hi, (n, system.n_joints))
    tips = rng.integers(0, len(TIPS), n)
    pin, model, data, cfg, fid = pinocchio_peer(path, system, q, tips)

    def pin_fk():
        out = np.empty((n, 4, 4))
        for k in range(n):
            pin.forwardKinematics(model, data, cfg[k])
            out[k] = pin.updateFramePlacement(model, data, fid[k]).homogeneous
        return out

    def pin_jac():
        for k in range(n):
            pin.computeFrameJacobian(model, data, cfg[k], fid[k],
                                     pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)

    err = float(np.abs(pin_fk() - system.fk(q, marker=tips)).max())
    t = {"kinecal fk": best(lambda: system.fk(q, marker=tips), rounds),
         "kinecal positions": best(lambda: system.positions(q, marker=tips), rounds),
         "pinocchio fk loop": best(pin_fk, rounds),
         "kinecal joint jacobian": best(lambda: system.joint_jacobian(q, marker=tips),
                                        rounds),
         "pinocchio frame jacobian loop": best(pin_jac, rounds),
         "kinecal identification jacobian": best(
             lambda: system.jacobian_t(q, marker=tips, outputs="pose"), rounds)}
    return {"n": n, "params": system.n_params, "max_fk_difference_m": err, "times": t}


def per_row_cost(n: int, rounds: int) -> dict:
    """Identification Jacobian per row and column, and calibration per row: the three-chain
    system against the left arm alone."""
    from kinecal import calibrate
    from kinecal.calibration.blocks.system_simulate import simulate_system
    from kinecal.calibration.serial.simulate import simulate
    from kinecal.io.urdf import load_urdf
    from kinecal.io.urdf_tree import load_urdf_system

    path = talos_path()
    system = load_urdf_system(path, TIPS)
    arm = load_urdf(path, tip_link=TIPS[0])
    single = load_urdf_system(path, TIPS[:1])  # the same chain as a system of one tip
    sim = simulate_system(system, n // len(TIPS), noise=1e-5, rng=1)
    one = simulate(arm, n, noise=1e-5, rng=1)
    alone = simulate_system(single, n, noise=1e-5, rng=1).data
    d = sim.data
    reach = np.mean([c.reach.size for c in system._chains])  # columns a row's chain writes
    jac_sys = best(lambda: system.jacobian_t(d.q, marker=d.marker), rounds)
    jac_one = best(lambda: arm.jacobian_t(one.data.q), rounds)
    cal = {"system": best(lambda: calibrate(system, d), max(1, rounds // 3)) / len(d),
           "one-tip system": best(lambda: calibrate(single, alone), max(1, rounds // 3))
           / len(alone),
           "chain": best(lambda: calibrate(arm, one.data), max(1, rounds // 3))
           / len(one.data)}
    return {"rows_system": len(d), "rows_chain": len(one.data),
            "jacobian_per_row_column_ns": {
                "system": 1e9 * jac_sys / (len(d) * reach),
                "chain": 1e9 * jac_one / (len(one.data) * arm.n_params)},
            "calibration_per_row_us": {k: 1e6 * v for k, v in cal.items()}}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    n, rounds = (600, 2) if args.quick else (3000, 5)
    k = kinematics(n, rounds)
    t = k["times"]
    print(f"TALOS, tips {', '.join(TIPS)}: {k['params']} parameters, {n} rows of random "
          f"tips; FK equal to pinocchio's to {k['max_fk_difference_m']:.1e} m")
    print(f"{'what':34s} {'us/row':>9s} {'pinocchio / kinecal':>20s}")
    pairs = [("kinecal fk", "pinocchio fk loop"),
             ("kinecal positions", "pinocchio fk loop"),
             ("kinecal joint jacobian", "pinocchio frame jacobian loop")]
    for mine, peer in pairs:
        print(f"{mine:34s} {1e6 * t[mine] / n:9.2f} {t[peer] / t[mine]:19.1f}x")
    for peer in ("pinocchio fk loop", "pinocchio frame jacobian loop"):
        print(f"{peer:34s} {1e6 * t[peer] / n:9.2f}")
    mine = "kinecal identification jacobian"
    print(f"{mine:34s} {1e6 * t[mine] / n:9.2f}   (6 x {k['params']} per row; "
          f"{t[mine] / t['kinecal fk']:.1f}x the FK)")
    rows = 1500 if args.quick else 5000
    c = per_row_cost(rows, rounds)
    j, cal = c["jacobian_per_row_column_ns"], c["calibration_per_row_us"]
    print(f"\nidentification Jacobian per row and column of the row's chain: system "
          f"{j['system']:.2f} ns, one chain {j['chain']:.2f} ns "
          f"({j['system'] / j['chain']:.2f}x)")
    print(f"calibration per row ({c['rows_system']} rows of 3 chains, {c['rows_chain']} of "
          f"one): system {cal['system']:.1f} us; the left arm as a system of one tip "
          f"{cal['one-tip system']:.1f} us ({cal['system'] / cal['one-tip system']:.2f}x); "
          f"the left arm on the serial path {cal['chain']:.1f} us "
          f"({cal['system'] / cal['chain']:.2f}x)")


if __name__ == "__main__":
    main()
