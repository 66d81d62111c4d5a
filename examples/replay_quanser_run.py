"""Replay a real Quanser rotary flexible link run on its calibrated twin.

A CU Boulder lab log (docs/real-arms.md) holds the hub angle, the tip gauge, the lab's
tip state feedback V = K1 (theta_ref - theta) - K2 d - K3 theta' - K4 d' and its
reference. The twin (preset quanser_cuboulder_calibrated: the link, the servo's gear,
motor and stick-slip friction, the gauge's lag) runs the same law in closed loop on the
recorded reference; printed: the hub and tip RMS errors against the lab (the docs: a
median of 0.0145 rad and 5.6 mm over 17 held-out runs). Writes replay.png.

    python examples/replay_quanser_run.py ../shared/data/real     # 10 s of lab data, ~10 s
"""
import sys
from pathlib import Path

from flex_control.state_feedback import lab_policy_factory
from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder_file
from flex_twin.real_arms.quanser_twin import stored_calibrated_arm
from flex_twin.real_arms.replay import plot_replay, replay

RUN = "flexarm_K1K2K3_6_-5_213"                  # a run the calibration never saw
data = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/real")
files = sorted((data / CUBOULDER).glob(f"*/**/{RUN}"))
if not files:
    sys.exit(f"no lab data: {data / CUBOULDER} holds no {RUN} (give the folder of the real "
             "data, e.g. ../shared/data/real, as the argument)")
run = read_cuboulder_file(files[0])
twin = FlexArmModel(stored_calibrated_arm(run.kind))
result = replay(twin, run, lab_policy_factory)         # closed loop, the recorded reference
m = result.metrics
print(f"{run.name}: {m['duration_s']:.1f} s, gains {run.gains.tolist()}")
print(f"hub RMS = {m['hub_rms_rad']:.4f} rad, tip RMS = {1e3 * m['tip_rms_m']:.2f} mm")
plot_replay([result], "replay.png", title=f"{run.name} on {twin.arm.name}")
print("wrote replay.png")
