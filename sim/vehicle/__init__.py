"""The quadrotor itself: airframe and rotor parameters, motors, the SE(3) controller, physics settings."""
