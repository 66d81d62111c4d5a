"""Natural frequencies and the static tip of the thesis Example 1 arm (VALIDATION.md B).

Two 2 m aluminium links, 2 wavelet variables per link, clamped joints: the modes of the
linearized model (thesis Sec. II.6: K phi = omega^2 M phi) give 1.323 and 8.359 Hz as in
the thesis; a 10 N m tip torque without gravity turns the tip by 7.81 deg and lifts it by
273 mm (thesis statics, Theorem 1: exact with the wavelets). Writes modes.png.

    python examples/modes_and_statics.py
"""
import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.plots import plot_modes
from flex_model.statics import TipLoad, static_equilibrium

model = FlexArmModel(load_arm("thesis_example1"))
modes = natural_modes(model, joints="clamped")
f1, f2 = modes.frequencies_hz[:2]
print(f"natural frequencies (Hz): {f1:.3f}, {f2:.3f}")

no_gravity = FlexArmModel(load_arm("thesis_example1").without_gravity())
tip = static_equilibrium(no_gravity, joints="clamped", load=TipLoad(torque=10.0), linear=True)
print(f"tip torque 10 N m: rotation = {np.degrees(tip.tip_rotation):.2f} deg, "
      f"displacement = {1e3 * tip.tip_displacement:.1f} mm")

plot_modes(model, modes, "modes.png", count=2, title="thesis Example 1: first two modes")
print("wrote modes.png")
