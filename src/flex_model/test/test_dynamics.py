"""Equations of motion against an independent derivation of the Lagrangian.

The reference below writes the kinetic energy of every link as thesis Eq. (7), the chain
of link origins as Eqs. (20)-(21) and gravity as Eq. (16), and differentiates the
Lagrangian by complex steps (exact to rounding):

    d/dt (B v) - dT/dq + dU_g/dq = B a + B_dot v - dT/dq + dU_g/dq.

The model evaluates the same equations by d'Alembert's principle over the particles with
a backward recursion (flex_model.kernels); both must agree to 1e-8 relative.
"""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel

H = 1e-30  # complex step


def link_data(model):
    """Per-link constants of thesis Eq. (8)-(11), end bodies included, from the bases."""
    out = []
    m_plus_pay, j_plus_pay = model.payload
    for i, (lk, b) in enumerate(zip(model.arm.links, model.bases)):
        mp = lk.M_plus + (m_plus_pay if i == model.n_links - 1 else 0.0)
        jp = lk.J_plus + (j_plus_pay if i == model.n_links - 1 else 0.0)
        out.append(dict(L=lk.length, Mp=mp, Jp=jp, M=lk.M_minus + b.mass + mp,
                        J=lk.J_minus + b.second_moment + jp, N=mp * lk.length + b.first_moment,
                        Bf=b.Bw, h=b.h, k=b.k))
    return out


def kinetic_energy(model, q, v):
    """T = sum of thesis Eq. (7) over the links, origins velocities by Eq. (20)."""
    T = 0.0
    xd = yd = 0.0 * q[0]
    for i, d in enumerate(link_data(model)):
        s = model.flex_slice(i)
        a, ad = q[model.off[i]], v[model.off[i]]
        qf, vf = q[s], v[s]
        dn, ddn, dgn = qf[-2], vf[-2], vf[-1]
        Mp, Jp, L = d["Mp"], d["Jp"], d["L"]
        T += 0.5 * (d["M"] * (xd**2 + yd**2) + Mp * ddn**2 + Jp * dgn**2
                    + (d["J"] + qf @ d["Bf"] @ qf + Mp * (L**2 + dn**2)) * ad**2
                    + vf @ d["Bf"] @ vf
                    + 2 * (d["k"] @ vf + Jp * dgn + Mp * L * ddn) * ad
                    - 2 * (Mp * dn + d["h"] @ qf) * ad * (xd * np.cos(a) + yd * np.sin(a))
                    + 2 * (d["N"] * ad + d["h"] @ vf + Mp * ddn)
                    * (yd * np.cos(a) - xd * np.sin(a)))
        # Eq. (20)-(21): velocity of the next origin
        xd = xd + (-L * np.sin(a) - dn * np.cos(a)) * ad - np.sin(a) * ddn
        yd = yd + (L * np.cos(a) - dn * np.sin(a)) * ad + np.cos(a) * ddn
    return T


def gravity_energy(model, q, g):
    """Eq. (16) per link with y_o from the chain (g along -y)."""
    U = 0.0
    yo = 0.0 * q[0]
    for i, d in enumerate(link_data(model)):
        s = model.flex_slice(i)
        a = q[model.off[i]]
        qf = q[s]
        U += d["M"] * g * yo + d["N"] * g * np.sin(a) + (d["Mp"] * qf[-2] + d["h"] @ qf) * g \
            * np.cos(a)
        yo = yo + d["L"] * np.sin(a) + qf[-2] * np.cos(a)
    return U


def reference_eom(model, q, v, a, g):
    n = len(q)
    E = np.eye(n)

    def B(qq):
        T0 = np.array([kinetic_energy(model, qq, E[j]) for j in range(n)])
        out = np.empty((n, n), dtype=complex)
        for i in range(n):
            for j in range(n):
                out[i, j] = kinetic_energy(model, qq, E[i] + E[j]) - T0[i] - T0[j] \
                    if i != j else 2 * T0[i]
        return out

    Bq = B(q.astype(complex)).real
    Bdot_v = (B(q + 1j * H * v) @ v).imag / H
    dTdq = np.array([kinetic_energy(model, q + 1j * H * E[k], v).imag / H for k in range(n)])
    dUdq = np.array([gravity_energy(model, q + 1j * H * E[k], g).imag / H for k in range(n)])
    return Bq, Bq @ a + Bdot_v - dTdq + dUdq


@pytest.mark.parametrize("preset, nv, payload", [
    ("thesis_single_link", 4, (0.0, 0.0)),
    ("thesis_example1", 4, (0.3, 0.02)),
    ("thesis_three_link", 2, (0.5, 0.1)),
])
def test_equations_of_motion_match_lagrangian(preset, nv, payload):
    model = FlexArmModel(load_arm(preset, nv).with_vars_per_link(nv))
    model = model.with_gravity((0.0, -9.81))
    model.set_payload(*payload)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.normal(size=model.nq) * 0.3
        v = rng.normal(size=model.nq)
        a = rng.normal(size=model.nq)
        Bref, fref = reference_eom(model, q, v, a, 9.81)
        B = model.mass_matrix(q)
        np.testing.assert_allclose(B, Bref, rtol=1e-8, atol=1e-8 * np.abs(Bref).max())
        f = model.inverse_dynamics(q, v, a)
        np.testing.assert_allclose(f, fref, rtol=1e-8, atol=1e-8 * np.abs(fref).max())


def test_mass_matrix_symmetric_positive_definite():
    model = FlexArmModel(load_arm("thesis_three_link", 8))
    q = np.random.default_rng(1).normal(size=model.nq) * 0.1
    B = model.mass_matrix(q)
    np.testing.assert_allclose(B, B.T, rtol=0, atol=1e-12 * np.abs(B).max())
    assert np.linalg.eigvalsh(B).min() > 0


def test_joint_coordinates_round_trip_and_encoder_angle():
    model = FlexArmModel(load_arm("thesis_example1", 4))
    theta = np.array([0.3, -0.2])
    flex = np.array([0.01, 0.02, 0.03, 0.04, -0.01, 0.0, 0.02, 0.05])
    q = model.q_from_joint_angles(theta, flex)
    np.testing.assert_allclose(model.joint_angles(q), theta, atol=1e-15)
    # theta_2 = alpha_2 - alpha_1 - gamma_1n
    assert q[model.off[1]] == pytest.approx(0.3 + 0.04 - 0.2)


def particle_points(model):
    """Per link: z, mass weights, W(z), S(z) at the root, 10 Gauss points per interval and
    the tip (end masses at both ends)."""
    xi, wxi = np.polynomial.legendre.leggauss(10)
    m_pay = model.payload[0]
    out = []
    for i, (lk, b) in enumerate(zip(model.arm.links, model.bases)):
        zs, ws = [], []
        for z0, z1 in zip(b.nodes[:-1], b.nodes[1:]):
            zs.append(z0 + 0.5 * (z1 - z0) * (xi + 1))
            ws.append(0.5 * (z1 - z0) * wxi)
        z, w = np.concatenate(zs), np.concatenate(ws)
        mw = w * lk.segments[0].properties(z / lk.length)[1]
        mp = lk.M_plus + (m_pay if i == model.n_links - 1 else 0.0)
        z = np.concatenate([[0.0], z, [lk.length]])
        mw = np.concatenate([[lk.M_minus], mw, [mp]])
        out.append((z, mw, b.shape_matrix(z), b.shortening_matrix(z)))
    return out


def second_order_lagrangian(model, points, q, v, g):
    """T and U_g of the second-order kinematics by direct quadrature of the particles:
    p = o + (z - u) e1 + d e2, u = 1/2 int_0^z d'^2 dz."""
    T = 0.0
    U = 0.0
    o = np.zeros(2, dtype=q.dtype)
    od = np.zeros(2, dtype=q.dtype)
    j_pay = model.payload[1]
    for i, (lk, (z, mw, W, S)) in enumerate(zip(model.arm.links, points)):
        s = model.flex_slice(i)
        a, ad, qf, vf = q[model.off[i]], v[model.off[i]], q[s], v[s]
        e1 = np.array([np.cos(a), np.sin(a)])
        e2 = np.array([-np.sin(a), np.cos(a)])
        jp = lk.J_plus + (j_pay if i == model.n_links - 1 else 0.0)
        d, dd = W @ qf, W @ vf
        u = 0.5 * np.einsum("j,kjl,l->k", qf, S, qf)
        ud = np.einsum("j,kjl,l->k", qf, S, vf)
        r = z - u
        p = o[None, :] + r[:, None] * e1 + d[:, None] * e2
        pd = (od[None, :] - ud[:, None] * e1 + (r * ad)[:, None] * e2 + dd[:, None] * e2
              - (d * ad)[:, None] * e1)
        T += 0.5 * np.sum(mw * np.sum(pd * pd, axis=1))
        T += 0.5 * lk.J_minus * ad**2 + 0.5 * jp * (ad + vf[-1]) ** 2
        U += g * np.sum(mw * p[:, 1])
        o, od = p[-1], pd[-1]
    return T, U


def test_second_order_kinematics_match_their_lagrangian():
    arm = load_arm("thesis_three_link", 4).with_kinematics("second_order")
    model = FlexArmModel(arm)
    model.set_payload(0.4, 0.05)
    n = model.nq
    E = np.eye(n)
    rng = np.random.default_rng(3)
    q = rng.normal(size=n) * 0.3
    v = rng.normal(size=n)
    acc = rng.normal(size=n)
    pts = particle_points(model)
    kin = lambda qq, vv: second_order_lagrangian(model, pts, qq, vv, 9.81)[0]  # noqa: E731

    def B(qq):
        t0 = np.array([kin(qq, E[j]) for j in range(n)])
        return np.array([[kin(qq, E[i] + E[j]) - t0[i] - t0[j] if i != j else 2 * t0[i]
                          for j in range(n)] for i in range(n)])

    Bq = B(q.astype(complex)).real
    Bdot_v = (B(q + 1j * H * v) @ v).imag / H
    dT = np.array([kin(q + 1j * H * E[k], v).imag / H for k in range(n)])
    dU = np.array([second_order_lagrangian(model, pts, q + 1j * H * E[k], v, 9.81)[1].imag / H
                   for k in range(n)])
    fref = Bq @ acc + Bdot_v - dT + dU
    np.testing.assert_allclose(model.mass_matrix(q), Bq, rtol=1e-8,
                               atol=1e-8 * np.abs(Bq).max())
    np.testing.assert_allclose(model.inverse_dynamics(q, v, acc), fref, rtol=1e-8,
                               atol=1e-8 * np.abs(fref).max())
    # and the gravity potential used for the energy is the same
    assert model.energy(q, v)["gravity"] == pytest.approx(
        second_order_lagrangian(model, pts, q, v, 9.81)[1], rel=1e-10)
