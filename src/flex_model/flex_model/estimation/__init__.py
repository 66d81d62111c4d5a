"""State estimation and online adaptation of the flexible arm (issue 45; docs/estimation.md).

An extended Kalman filter on the arm's nonlinear model (FlexArmModel, planar, or
SpatialArmModel), gain-scheduled: Jacobians every ``relinearize_every`` samples, the
exponential-Euler discretization in between. ROS-free; the live path (``Estimator.step``)
and the offline path (``estimate_recording``) are the same code::

    from flex_model.estimation import (Measurement, EstimatorSettings, Estimator,
                                       estimate_recording)
    m = Measurement(name="q1", kind="joint_angle", index=0, std=1e-3, delay=0.0,
                    quantum=0.0)
    s = EstimatorSettings(sample_period=1e-3, adapt=("coulomb_friction:0", "payload_mass"),
                          torque_noise=0.1, modal_noise=0.0, relinearize_every=10)
    est = Estimator(model, [m, ...], s)
    est.reset(q0, v0, P0=None)
    sample = est.step(u, y)   # u: joint torques (voltages on dc_motor joints), held over
                              # the sample; y: one reading per measurement, NaN = missing
    result = estimate_recording(model, times, inputs, Y, measurements, s, q0=None, v0=None)

``Measurement`` kinds (one scalar each; flex_model.estimation.measurements): joint_angle,
joint_rate, motor_angle (joint ``index``), tip_deflection, strain (link ``index``),
tip_acceleration, tip_position (``component``). Variance std^2 + quantum^2 / 12; a
``delay`` (s) is read against the estimate of that time.

``Sample`` (after the sample's correction): t, q, v, state_cov (the full covariance of
[q; v; p]), joint_angles(_std), joint_rates(_std), tip_deflections(_std) (planar: per
link; spatial: per link x (v, w, twist)), tip_position (3, base frame), tip_position_cov
(3 x 3), tip_orientation (quaternion x, y, z, w) and tip_pose_cov (6 x 6: x, y, z, rotation
about x, y, z, as geometry_msgs/PoseWithCovariance), innovation and innovation_cov (over all
measurements, NaN where missing), nis and nis_dof of the sample, nis_mean and
nis_95_fraction (running: the fraction of samples with NIS below the chi2 95 % bound of
their dimension), parameters and parameter_std (name ->
value). ``EstimationResult``: the same fields as arrays over time (parameters: name ->
array) and ``summary`` (samples, nis_mean, nis_dof_mean, nis_95_fraction, final
parameters and stds).

Adapted parameters (``adapt``, random walks): ``coulomb_friction:<joint>``,
``viscous_friction:<joint>``, ``payload_mass``, ``link_stiffness:<link>`` (scale on EI);
with ``adapt_horizon`` (s) the joint frictions are instead fitted by least squares on the
momentum balance over that window (``horizon.HorizonFit``) and considered by the filter.
"""
from .filter import Estimator, EstimatorSettings, Sample
from .measurements import KINDS, Measurement
from .recording import EstimationResult, estimate_recording

__all__ = ["Estimator", "EstimatorSettings", "Sample", "Measurement", "KINDS",
           "EstimationResult", "estimate_recording"]
