"""flex_control: controllers for the flex-twin flexible-link arm models.

Core (numpy/scipy/yaml/flex_model only):

- :mod:`.laws`: ``PDLikeCascade`` (seed 000 Eq. 45), ``DecentralizedPD`` (thesis Eq. 95 +
  nominal feed-forward), ``hold_reference``, ``as_policy``;
- :mod:`.closed_loop`: the closed loop linearized along a nominal trajectory;
- :mod:`.design`: gain-scheduled design by cyclic coordinate ascent (thesis V.2);
- :mod:`.gain_schedule`: ``GainSchedule`` (interpolation, YAML);
- :mod:`.ltv`: LTV free/impulse responses and frozen-time margins (thesis V.3);
- :mod:`.tracking`: nonlinear closed-loop runs along a trajectory;
- :mod:`.step_response`: seed 000's step simulations (VALIDATION.md section G);
- :mod:`.nominal`: quasi-static nominal trajectories, NPZ files;
- :mod:`.params`: the controller node's parameters;
- :mod:`.cli`: ``flex-twin control step|design|check``.

ROS: :mod:`.controller_node` (``ControllerNode``), :mod:`.ros_conversions`.
"""
import flex_model as _flex_model  # noqa: F401,E402  (the ROS environment first)
