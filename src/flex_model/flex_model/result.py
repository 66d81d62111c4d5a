"""The one result of a simulation run of any arm (planar fixed, variable or exact;
spatial): the samples, the run's status and step advice, its summary and CSV table.

The arm-kind specifics are the model's: a planar model's joint angles are G q
(thesis Eq. 1's joint coordinates), a spatial model's (spatial/dynamics.py) the
coordinates at ``model.off``; the CSV columns and summary follow the arm.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .effects.contact import CT_ON
from .solvers.status import FINISHED, message


@dataclass
class SimulationResult:
    """Samples of a run: t (s), q, v (n, nq), joint torques tau (N m or N; n, n_joints);
    ``status`` (solvers.status code) and ``message``; ``advice``: the scenario's
    step_advice.StepAdvice when the run was advised."""

    model: object
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    stats: dict = field(default_factory=dict)
    u: np.ndarray = None        # held policy input at the samples (planar)
    inputs: tuple = None        # the compiled input data (planar integrators.py E)
    bristles: np.ndarray = None  # bristle deflections z (rad) of stick-slip joints
    status: int = FINISHED
    message: str = message(FINISHED)
    advice: object = None

    @property
    def spatial(self) -> bool:
        """A spatial arm's run (spatial.dynamics.SpatialArmModel)."""
        from .spatial.dynamics import SpatialArmModel
        return isinstance(self.model, SpatialArmModel)

    @property
    def joint_angles(self) -> np.ndarray:
        """(n, n_joints) joint values (rad; m on a prismatic joint)."""
        return self.q[:, self.model.off] if self.spatial else self.q @ self.model.G.T

    @property
    def joint_rates(self) -> np.ndarray:
        return self.v[:, self.model.off] if self.spatial else self.v @ self.model.G.T

    @property
    def tip_positions(self) -> np.ndarray:
        """(n, 2) planar, (n, 3) spatial: the last link's tip, base frame (m)."""
        if self.spatial:
            return np.array([self.model.tip_position(q) for q in self.q])
        return np.array([self.model.link_origins(q)[-1] for q in self.q])

    @property
    def contact_forces(self) -> np.ndarray:
        """(n, 2) planar, (n, 3) spatial: force of the contact surface on the tip (N, base
        frame)."""
        return np.array([self.model.contact_force(q, v) for q, v in zip(self.q, self.v)])

    @property
    def tip_deflections(self) -> np.ndarray:
        """Planar (n, n_links): each link's tip deflection (m; exact kinematics: the exact
        offsets); spatial (n, flexible links, 2): y, z of :meth:`link_deflections`."""
        if self.spatial:
            d = self.link_deflections()
            return np.stack([np.column_stack([v["y"], v["z"]]) for v in d.values()], axis=1)
        if self.model.arm.kinematics == "exact":
            return np.array([self.model.tip_deflections(q) for q in self.q])
        return self.q[:, [self.model.tip_deflection_index(i)
                          for i in range(self.model.n_links)]]

    # ------------------------------------------------------------ planar arms
    @property
    def stick_slip_torques(self) -> np.ndarray:
        """(n, n_links): torque of the stick-slip friction on every actuator coordinate
        (N m; zero at joints without the effect)."""
        z = self.bristles if self.bristles is not None else np.zeros((len(self.t), 0))
        return np.array([self.model.stick_slip_torques(v, zk) for v, zk in zip(self.v, z)])

    @property
    def motor_angles(self) -> np.ndarray:
        """(n, n_elastic_joints): motor coordinates of the elastic joints (rad, link side)."""
        m = self.model
        return self.q[:, m.nq_arm:m.nq_arm + len(m.elastic_joints)]

    def link_tips(self) -> np.ndarray:
        """(n, n_links, 2): the tip of every link."""
        return np.array([self.model.link_origins(q)[1:] for q in self.q])

    @property
    def tip_rotations(self) -> np.ndarray:
        return self.q @ self.model.tip_rotation_matrix().T

    # ------------------------------------------------------------ spatial arms
    def link_deflections(self) -> dict:
        """Spatial: {link name: {'y', 'z', 'twist', 'y_rate', 'z_rate', 'twist_rate'}} (n,)
        at the tip of every flexible link (m, rad): v along the beam's y, w along its z,
        the twist phi (seed 003 Eq. 19); exact kinematics: the tip's r_y(L), r_z(L)."""
        m, out = self.model, {}
        for i, (lk, b) in enumerate(zip(m.arm.links, m.beams)):
            if b is None:
                continue
            s = m.flex_slice(i).start
            iv, iw = s + b.tip_v, s + b.tip_w
            d = {"y": self.q[:, iv], "z": self.q[:, iw],
                 "y_rate": self.v[:, iv], "z_rate": self.v[:, iw]}
            if b.rule is not None:
                d = _exact_tips(b, self.q[:, s:s + 2 * b.nv], self.v[:, s:s + 2 * b.nv])
            zero = np.zeros(len(self.t))
            d["twist"], d["twist_rate"] = (zero, zero) if b.tip_phi is None else \
                (self.q[:, s + b.tip_phi], self.v[:, s + b.tip_phi])
            out[lk.name] = d
        return out

    # ------------------------------------------------------------ output
    def table(self) -> tuple[list[str], np.ndarray]:
        """CSV columns and data (SI units, rad): t, q<i>, v<i>, tau<i>; planar: tip_x|y,
        link<i>_tip_deflection, link<i>_tip_rotation, motor angles qm<i> of elastic joints;
        spatial: <link>_tip_deflection_y|z and <link>_tip_twist per flexible link,
        tip_x|y|z; and contact_fx|fy(|fz) with a contact surface."""
        n = self.model.n_links
        names = (["t"] + [f"q{i + 1}" for i in range(n)] + [f"v{i + 1}" for i in range(n)]
                 + [f"tau{i + 1}" for i in range(n)])
        cols = [self.t[:, None], self.joint_angles, self.joint_rates, self.tau]
        more = self._spatial_columns() if self.spatial else self._planar_columns()
        names += [nm for nm, _ in more]
        cols += [c for _, c in more]
        return names, np.column_stack(cols)

    def _planar_columns(self) -> list:
        m = self.model
        out = [(f"tip_{a}", c) for a, c in zip("xy", self.tip_positions.T)]
        out += [(f"link{i + 1}_tip_deflection", c)
                for i, c in enumerate(self.tip_deflections.T)]
        out += [(f"link{i + 1}_tip_rotation", c) for i, c in enumerate(self.tip_rotations.T)]
        out += [(f"qm{i + 1}", c) for i, c in zip(m.elastic_joints, self.motor_angles.T)]
        if m.contact[CT_ON] > 0:
            out += [(f"contact_f{a}", c) for a, c in zip("xy", self.contact_forces.T)]
        return out

    def _spatial_columns(self) -> list:
        out = []
        for name, d in self.link_deflections().items():
            out += [(f"{name}_tip_deflection_y", d["y"]), (f"{name}_tip_deflection_z", d["z"]),
                    (f"{name}_tip_twist", d["twist"])]
        out += [(f"tip_{a}", c) for a, c in zip("xyz", self.tip_positions.T)]
        if self.model.contact is not None:
            out += [(f"contact_f{a}", c) for a, c in zip("xyz", self.contact_forces.T)]
        return out

    def summary(self) -> dict:
        """The run's figures (``flex-twin simulate``): final joint values and tip, max |tip
        deflection| per link (planar mm; spatial y, z mm and twist mrad per flexible link)."""
        if not self.spatial:
            return {"vars_per_link": [lk.n_vars for lk in self.model.arm.links],
                    "final_joint_angles_deg": np.degrees(self.joint_angles[-1]).tolist(),
                    "final_tip_m": self.tip_positions[-1].tolist(),
                    "max_abs_tip_deflection_mm":
                    (1e3 * np.max(np.abs(self.tip_deflections), axis=0)).tolist()}
        defl = {k: {"y_mm": float(1e3 * np.max(np.abs(d["y"]))),
                    "z_mm": float(1e3 * np.max(np.abs(d["z"]))),
                    "twist_mrad": float(1e3 * np.max(np.abs(d["twist"])))}
                for k, d in self.link_deflections().items()}
        return {"spatial": True, "coordinates": int(self.model.nq),
                "newton_iterations": self.stats["newton_iterations"],
                "joint_names": self.model.arm.joint_names,
                "final_joint_values": self.joint_angles[-1].tolist(),
                "final_tip_m": self.tip_positions[-1].tolist(),
                "max_abs_tip_deflection": defl}

    def to_csv(self, path) -> None:
        names, data = self.table()
        np.savetxt(path, data, delimiter=",", header=",".join(names), comments="",
                   fmt="%.17g")


def _exact_tips(b, f, g) -> dict:
    """The tip's lateral displacements r_y(L), r_z(L) and their rates of link data ``b``
    (spatial.dynamics.BeamData, exact kinematics) at bending variables f, rates g (n, 2 nv)."""
    nv = b.nv
    y, z, yr, zr = (np.zeros(len(f)) for _ in range(4))
    for k, (fk, gk) in enumerate(zip(f, g)):
        r, Jv, Jw = (a[-1] for a in b.exact_points(fk[:nv], fk[nv:]))
        y[k], z[k] = r[1], r[2]
        yr[k], zr[k] = Jv[1:] @ gk[:nv] + Jw[1:] @ gk[nv:]
    return {"y": y, "z": z, "y_rate": yr, "z_rate": zr}
