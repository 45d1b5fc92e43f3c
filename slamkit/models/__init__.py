"""Kinematic and sensor models: pure functions on batch-first numpy arrays (imports geometry only).

Kinematics (state ``world_xytheta_body`` (..., 3)):

* ``diff_drive``   -- ``DiffDrive`` wheel kinematics; exact-arc ``motion``/``motion_jacobians``,
  ``motion_straight``, ``process_noise`` (Q = L M L^T), ``odometry_from_ticks``, ``integrate_odometry``
* ``bicycle``      -- ``Bicycle`` (wheelbase, steering limit, curvature, ICC, motion + Jacobians)
* ``tracked``      -- ``Tracked`` skid-steer with slip ratios and ICR shifts (Martinez et al. 2005)
* ``omni``, ``mecanum`` -- ``Omni3``, ``Mecanum`` holonomic wheel kinematics
* ``planar``       -- exact SE(2) integration of a body twist, shared by the models above

Sensors:

* ``range_bearing`` -- ``observe``/``inverse_observe`` + Jacobians, ``RangeBearingSensor``
* ``gps``          -- ``Gps`` presets (consumer, dgps, rtk), lever arm, Gauss-Markov error
* ``imu``          -- ``ImuNoise`` presets, ``simulate_imu`` (white noise + bias random walk)
* ``encoders``     -- ``Encoder`` tick quantisation
* ``lidar``        -- ``BeamModel`` and ``LikelihoodFieldModel`` (ray casting lives in slamkit.maps)
* ``camera``       -- ``PinholeCamera`` with radial-tangential distortion
* ``stereo``       -- ``StereoCamera``, Z = f b / d and its uncertainty

Submodules are imported explicitly (``from slamkit.models import diff_drive``); nothing is
re-exported here so importing one model does not pull in scipy for the others.
"""
