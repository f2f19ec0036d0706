"""Models any plugin can build on: rate integration, planar kinematics (see fusionkit.api)."""
