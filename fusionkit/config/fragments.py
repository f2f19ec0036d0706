"""JSON-schema fragments every component's schema uses (public through fusionkit.api, API 1.12), and the standard
gravity fusionkit's models share."""

NAME_SCHEMA = {"type": "string"}                              # a stream, robot or parameter name
POSITIVE_SCHEMA = {"type": "number", "exclusiveMinimum": 0}   # a sigma, a rate, a length
NON_NEGATIVE_SCHEMA = {"type": "number", "minimum": 0}        # a noise that may be zero, a margin
GRAVITY = 9.81  # m/s^2: the default of every model's `gravity` (a description or entry may give its own)
