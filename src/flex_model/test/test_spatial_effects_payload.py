"""A payload at the tip of a spatial arm (issue 25): the arm file's ``payload`` (mass,
centre offset, 3 x 3 inertia in the last link's end frame) lumped with the last end body
by the parallel-axis theorem; its first bending frequency against the clamped-free beam
with a tip mass; bad payloads refused."""
import copy

import numpy as np
import pytest
from scipy.optimize import brentq

from flex_model.config import ConfigError
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes
from flex_model.spatial.compiled import CompiledSpatialModel

ARM = {"name": "payload", "gravity": [0.4, -1.0, -9.81], "links": [
    {"joint": {"name": "j1", "d": 0.2, "alpha": 1.5707963267948966},
     "end_body": {"mass": 1.0, "inertia": [0.01, 0.02, 0.015]}},
    {"joint": {"name": "j2", "a": 0.5, "alpha": 0.4},
     "flexible": {"variables": 4, "torsion_variables": 2,
                  "section": {"EI_y": 40.0, "EI_z": 20.0, "GJ": 15.0, "rhoA": 0.8,
                              "rhoJ": 1e-3}},
     "end_body": {"mass": 0.5, "offset": [0.01, 0.0, 0.02],
                  "inertia": [[2e-3, 1e-4, 0.0], [1e-4, 3e-3, 2e-4], [0.0, 2e-4, 1e-3]]}}]}
PAYLOAD = {"mass": 0.3, "offset": [0.05, -0.02, 0.03],
           "inertia": [[1e-3, 0.0, 2e-4], [0.0, 2e-3, 0.0], [2e-4, 0.0, 1.5e-3]]}


def test_payload_is_the_lumped_end_body():
    """M, c (velocity terms and gravity) at random states, Python and compiled, of the
    arm with a payload = the arm whose end body is the lumped body written out by hand
    (m = m1 + m2, c = (m1 c1 + m2 c2) / m, I = sum I_k + m_k (|d_k|^2 E - d_k d_k^T))."""
    with_payload = dict(copy.deepcopy(ARM), payload=PAYLOAD)
    m1, c1 = 0.5, np.array([0.01, 0.0, 0.02])
    I1 = np.array(ARM["links"][1]["end_body"]["inertia"])
    m2, c2, I2 = 0.3, np.array(PAYLOAD["offset"]), np.array(PAYLOAD["inertia"])
    m = m1 + m2
    c = (m1 * c1 + m2 * c2) / m
    d1, d2 = c1 - c, c2 - c
    inertia = I1 + m1 * (d1 @ d1 * np.eye(3) - np.outer(d1, d1)) + \
        I2 + m2 * (d2 @ d2 * np.eye(3) - np.outer(d2, d2))
    lumped = copy.deepcopy(ARM)
    lumped["links"][1]["end_body"] = {"mass": m, "offset": c.tolist(),
                                      "inertia": inertia.tolist()}
    a, b = (SpatialArmModel(spatial_arm_from_dict(x)) for x in (with_payload, lumped))
    bare = SpatialArmModel(spatial_arm_from_dict(ARM))
    ca = CompiledSpatialModel(a)
    rng = np.random.default_rng(11)
    for _ in range(3):
        q = rng.normal(scale=0.3, size=a.nq)
        v = rng.normal(scale=2.0, size=a.nq)
        Ma, cc = a.terms(q, v)
        Mb, cb = b.terms(q, v)
        scale = np.max(np.abs(Mb))
        assert np.max(np.abs(Ma - Mb)) < 1e-13 * scale
        assert np.max(np.abs(cc - cb)) < 1e-12 * np.max(np.abs(cb))
        Mc, ccc = ca.terms(q, v)
        assert np.max(np.abs(Mc - Mb)) < 1e-10 * scale
        assert np.max(np.abs(ccc - cb)) < 1e-10 * np.max(np.abs(cb))
        assert np.max(np.abs(bare.mass_matrix(q) - Ma)) > 1e-3 * scale   # it is there


def test_tip_payload_frequency_against_the_clamped_free_beam_with_tip_mass():
    """A held joint and a uniform beam (EI_z 2, rhoA 0.5 kg/m, L 0.8 m) with a 0.2 kg
    point payload: the first in-plane frequency solves 1 + cos(bL) cosh(bL) + r bL
    (cos(bL) sinh(bL) - sin(bL) cosh(bL)) = 0, r = M / (rhoA L), w = b^2 sqrt(EI / rhoA)
    (8 variables: 3.5e-6 above, the Ritz upper bound)."""
    ei, rho, L, mp = 2.0, 0.5, 0.8, 0.2
    data = {"name": "tipmass", "gravity": [0.0, 0.0, 0.0], "links": [
        {"joint": {"name": "j1", "a": L, "motor": "locked"},
         "flexible": {"variables": 8, "torsion_variables": 0,
                      "section": {"EI_y": 50.0, "EI_z": ei, "GJ": 1.0, "rhoA": rho}}}],
        "payload": {"mass": mp}}
    model = SpatialArmModel(spatial_arm_from_dict(data))
    f = natural_modes(model, joints="clamped", coordinates=model.plane_indices("v")[1:])
    r = mp / (rho * L)

    def eq(x):
        return 1 + np.cos(x) * np.cosh(x) + r * x * (np.cos(x) * np.sinh(x)
                                                     - np.sin(x) * np.cosh(x))
    bl = brentq(eq, 0.5, 1.875104)
    omega = (bl / L) ** 2 * np.sqrt(ei / rho)
    # Rayleigh-Ritz with 4 wavelet intervals: an upper bound, 3.5e-6 above
    assert omega <= f.omega[0] < omega * (1 + 1e-5)
    assert omega < 0.8 * (1.875104 / L) ** 2 * np.sqrt(ei / rho)   # the payload lowers it


def test_bad_payload_names_the_field():
    data = dict(copy.deepcopy(ARM), payload={"mass": -1.0})
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "arm.yaml" in str(err.value) and "payload.mass" in str(err.value)
    data = dict(copy.deepcopy(ARM), payload={"mass": 1.0, "inertia": [1.0, -1.0, 0.0]})
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "payload.inertia" in str(err.value)
