"""Temporal motion retargeting (STMR §IV-B, §VI): Bayesian optimisation over the time scaling α of S segments,
each α scored by iLQR tracking of the deformed motion in the robot's full MuJoCo model."""
