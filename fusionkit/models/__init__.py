"""Models any plugin can build on: rate integration, planar kinematics, simulator building blocks
(see fusionkit.api)."""
