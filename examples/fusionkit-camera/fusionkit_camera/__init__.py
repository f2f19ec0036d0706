"""fusionkit-camera: pinhole camera intrinsics (a variable type fusionkit does not have) and the pixel factor
that calibrates them. See README.md."""
