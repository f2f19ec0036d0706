"""fusionkit-altimeter: an example third-party fusionkit plugin.

It adds one factor type and one simulator:

- `altimeter.height` — a barometric altimeter measuring the height of the robot's body with an
  unknown constant bias b (a scalar calibration parameter of the robot description):
  `z[k] = t_z(X_k) + b + noise`;
- `altimeter.demo` — a synthetic drone flight (VO-like odometry, sparse absolute poses and a
  biased altimeter) with its truth.

fusionkit finds it through the `fusionkit` entry-point group (see pyproject.toml); the hooks are
in `fusionkit_altimeter.plugin`. Nothing in fusionkit knows this package exists.
"""

__version__ = "0.1.0"
