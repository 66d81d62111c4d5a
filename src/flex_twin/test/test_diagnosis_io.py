"""Diagnosis inputs: controller YAML, CSV recording validation, CLI refusals (issue 8)."""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_twin.cli import main
from flex_model.config import ConfigError
from flex_twin.diagnosis.controller import (controller_from_dict, controller_to_dict,
                                             load_controller)
from flex_twin.diagnosis.recording import RecordingError, load_csv
from flex_model.dynamics import FlexArmModel

PD = {"controller": {"law": "pd", "kp": [200.0, 80.0], "kd": [20.0, 8.0], "period": 0.002,
                     "feedforward": "gravity"}}


def test_gravity_feedforward_is_the_static_torque_of_the_undeformed_arm():
    c = controller_from_dict(PD)
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    m = 2.0 * (0.020 ** 2 - 0.018 ** 2) * 2700.0        # kg per 2 m link
    ff = c.feedforward(model, np.array([[0.0, 0.0], [np.pi / 2, 0.0], [0.0, np.pi / 2]]))
    # horizontal arm: joint 1 carries m g (L/2) + m g (3L/2), joint 2 m g L/2
    assert ff[0] == pytest.approx([9.81 * m * 4.0, 9.81 * m * 1.0], rel=1e-9)
    assert np.abs(ff[1]).max() < 1e-12                 # arm straight up
    # link 2 vertical: joint 1 carries m g L/2 + m g L
    assert ff[2] == pytest.approx([9.81 * m * 3.0, 0.0], abs=1e-9)


def test_controller_validation_names_file_field_and_value(tmp_path):
    bad = {"controller": dict(PD["controller"], kd=[20.0])}
    with pytest.raises(ConfigError, match=r"controller\.kd: got \[20\.0\]; expected a list of 2"):
        controller_from_dict(bad, "c.yaml")
    sf = {"controller": {"law": "state_feedback", "period": 0.002,
                         "gains": [{"q1": 20.0, "w1": -40.0}],
                         "rate_gains": [{"q1": 1.5, "w2": 0.8}]}}
    c = controller_from_dict(sf)
    assert c.channels == ("q1", "w1", "w2")
    assert c.gains.tolist() == [[20.0, -40.0, 0.0]] and c.rate_gains.tolist() == [[1.5, 0, 0.8]]
    with pytest.raises(ConfigError, match="gains\\[0\\].x1"):
        controller_from_dict({"controller": dict(sf["controller"], gains=[{"x1": 1.0}])})
    import yaml
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(controller_to_dict(c)))
    assert load_controller(path).gains.tolist() == c.gains.tolist()


def _write(path, header, rows):
    path.write_text(",".join(header) + "\n" + "\n".join(",".join(map(str, r)) for r in rows))


HEADER = ["t", "q1", "v1", "tau1", "qset1"]


def test_csv_refusals_name_the_problem(tmp_path):
    rows = [[k * 0.002, 0.1, 0.0, 1.0, 0.1] for k in range(100)]
    p = tmp_path / "ok.csv"
    _write(p, HEADER, rows)
    rec = load_csv(p, 1)
    assert rec.dt == pytest.approx(0.002) and rec.residual_channels == ["q1", "v1", "tau1"]
    with pytest.raises(RecordingError, match="missing channel\\(s\\) q2, v2, tau2, qset2"):
        load_csv(p, 2)
    p2 = tmp_path / "trunc.csv"
    p2.write_text(p.read_text() + "\n0.2,0.1,0.0")
    with pytest.raises(RecordingError, match="line 102: 3 fields, header has 5"):
        load_csv(p2, 1)
    bad = [r[:] for r in rows]
    bad[40][0] = bad[39][0]
    _write(p2, HEADER, bad)
    with pytest.raises(RecordingError, match="not increasing"):
        load_csv(p2, 1)
    bad = [r[:] for r in rows]
    bad[7][1] = "nan"
    _write(p2, HEADER, bad)
    with pytest.raises(RecordingError, match="channel q1: non-finite value at sample 7"):
        load_csv(p2, 1)


def test_cli_refuses_corrupt_input_with_exit_2(tmp_path, capsys):
    import yaml
    ctl = tmp_path / "c.yaml"
    ctl.write_text(yaml.safe_dump(PD))
    data = tmp_path / "d.csv"
    _write(data, ["t", "q1", "v1", "tau1", "qset1", "q2", "v2"],
           [[k * 0.002, 0, 0, 0, 0, 0, 0] for k in range(100)])
    code = main(["diagnose", str(data), "--arm", "thesis_example1_motors", "--controller",
                 str(ctl), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "missing channel(s) tau2, qset2" in err[0]
    data.write_bytes(b"\x00\xff\xfe garbage")
    assert main(["diagnose", str(data), "--arm", "thesis_example1_motors", "--controller",
                 str(ctl)]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_bag_without_the_reference_topic_is_refused_by_name():
    from pathlib import Path
    bag = Path(__file__).resolve().parents[3] / "test" / "data" / "bags" / "model_lockstep"
    if not bag.exists():
        pytest.skip(f"golden bag {bag} not present")
    from flex_twin.diagnosis.sources import load_recording
    with pytest.raises(RecordingError, match="missing topic\\(s\\) /flex_planner/trajectory"):
        load_recording(bag, 2)


def test_updated_arm_yaml_loads_with_the_named_effects(tmp_path):
    import types

    import yaml

    from flex_model.arm import PRESET_DIR
    from flex_twin.diagnosis.baseline import baseline_parameters
    from flex_twin.diagnosis.hypotheses import library_hypotheses
    from flex_twin.diagnosis.recording import validate
    from flex_twin.diagnosis.report import write_arm_yaml
    nominal = load_arm("thesis_example1_motors")
    t = np.arange(100) * 0.002
    ch = {f"{k}{i}": np.sin(t + i) for k in ("q", "v", "tau", "qset") for i in (1, 2)}
    rec = validate(t, ch, 2, "mem")
    hyps = {h.label: h for h in library_hypotheses(nominal, rec, controller_from_dict(PD))}
    picks = [("joint_elasticity@joint2", [0.5, 2.0]), ("sensor_bias@joint1", [5.0]),
             ("stiffness@link1", [1.5]), ("joint_friction@joint1", [1.0, 1.0, 0.3, 0.0])]
    effects = [(hyps[lab], np.array(x)) for lab, x in picks]
    accepted = [types.SimpleNamespace(label=h.label, kind=h.kind, names=h.names,
                                      values=list(h.values(x)), ci=[0.0] * len(x), share=1.0)
                for h, x in effects]
    params = baseline_parameters(nominal)
    ctx = types.SimpleNamespace(baseline_params=params, nominal=nominal)
    diag = types.SimpleNamespace(contexts=(ctx,), verdict="named", accepted=accepted,
                                 final_effects=effects,
                                 scales={p.name: 1.02 for p in params})
    out = tmp_path / "arm.yaml"
    write_arm_yaml(out, PRESET_DIR / "thesis_example1_motors.yaml", diag)
    arm = load_arm(out)
    spring = arm.effect("joint_elasticity", "joint2")
    k_ref = hyps["joint_elasticity@joint2"].scale[0]
    assert spring["stiffness"] == pytest.approx(k_ref / 0.5)
    # the gear's rotor moved to the motor side: n^2 J_r of the recalibrated arm
    assert spring["motor_inertia"] == pytest.approx(100 ** 2 * 5e-5 * 1.02)
    assert arm.effect("gear", "joint2")["rotor_inertia"] == 0.0
    fr = arm.effect("joint_friction", "joint1")
    assert fr["static"] == pytest.approx(fr["coulomb"] * 1.3)
    assert arm.links[0].segments[0].E == pytest.approx(6.4e10 * 1.02 * 1.15)
    assert [(s.kind, s.bias) for s in arm.sensors] == [("joint_encoder", 5e-3)]
    assert yaml.safe_load(out.read_text())["name"] == "thesis_example1_motors_diagnosed"
    FlexArmModel(arm)


def test_stiffness_hypothesis_scales_EI_of_material_and_explicit_links(tmp_path):
    """+10 % E I moves a clamped link's first frequency by sqrt(1.1), whether the section is
    a material (E) or explicit (EI) one, and the updated raw YAML carries the same scale."""
    from flex_model.arm import arm_from_dict
    from flex_twin.diagnosis.baseline import scale_raw_link
    from flex_twin.diagnosis.hypotheses import Hypothesis
    from flex_model.modes import natural_modes
    explicit = {"name": "x", "gravity": [0.0, 0.0], "links": [
        {"length": 0.45, "section": {"shape": "explicit", "EI": 0.25, "m": 0.13}}]}
    hyp = Hypothesis("stiffness", "link1", ("relative_change",), (0.1,), (-7,), (20,),
                     (0.0,), ((1.0,),))
    for arm in (arm_from_dict(explicit), load_arm("thesis_single_link")):
        f0 = natural_modes(FlexArmModel(arm), joints="clamped").omega[0]
        stiffer, _ = hyp.apply(arm, np.array([1.0]))
        f1 = natural_modes(FlexArmModel(stiffer), joints="clamped").omega[0]
        assert f1 / f0 == pytest.approx(np.sqrt(1.1), rel=1e-9)
    raw = explicit["links"][0]
    scale_raw_link(raw, "EI", 1.1)
    assert raw["section"]["EI"] == pytest.approx(0.275)
    assert hyp.physical([0.1], [0.01], arm_from_dict(explicit))[0] == ("EI",)



def test_scaled_explicit_section_dumps_as_plain_yaml():
    """The updated arm of an explicit-section link (the Quanser handout preset) is written
    with yaml.safe_dump: the scaled E I and m are plain floats, not numpy scalars."""
    import yaml as _yaml

    from flex_twin.diagnosis.baseline import scale_raw_link
    lk = {"section": {"shape": "explicit", "EI": [0.25, 0.2], "m": 0.13}}
    scale_raw_link(lk, "EI", np.float64(1.1))
    scale_raw_link(lk, "m", np.float64(0.9))
    assert lk["section"]["EI"] == pytest.approx([0.275, 0.22])
    assert lk["section"]["m"] == pytest.approx(0.117)
    assert _yaml.safe_load(_yaml.safe_dump(lk)) == lk


def test_scaling_an_effect_parameter_left_out_of_the_yaml_scales_its_default():
    """A joint_friction entry without stribeck_velocity takes 0.01 rad/s (its off value);
    the baseline's scale of it is written as 0.01 x scale (it raised KeyError when the
    report was written, after the whole diagnosis)."""
    from flex_twin.diagnosis.baseline import ScaleParameter, scale_raw
    raw = {"effects": [{"type": "joint_friction", "joint": "joint1", "viscous": 0.2}]}
    params = [ScaleParameter("f.v", "effect", ("joint_friction", "joint1", "viscous"), 0.3),
              ScaleParameter("f.w", "effect", ("joint_friction", "joint1",
                                               "stribeck_velocity"), 0.5)]
    out = scale_raw(raw, params, [1.1, 1.2])["effects"][0]
    assert out["viscous"] == pytest.approx(0.22)
    assert out["stribeck_velocity"] == pytest.approx(0.012)
    assert "stribeck_velocity" not in raw["effects"][0]
