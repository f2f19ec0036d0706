"""The plugin's own tests.

    pip install -e examples/fusionkit-camera
    pytest examples/fusionkit-camera/tests
"""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from fusionkit.testing import check_factor_contract
from fusionkit_camera.factors import CameraPixel
from fusionkit_camera.intrinsics import CAL3_S2
from fusionkit_camera.residuals import pixel_residual
from fusionkit_camera.simulator import project


def test_contract():
    """Zero residual at the example, right shapes, analytic = numerical Jacobians (also away from it)."""
    check_factor_contract(CameraPixel)


def test_residual_matches_gtsams_pinhole_camera():
    """The same pixel as gtsam.PinholeCameraCal3_S2 for a camera 2 m from a point, and as the simulator's."""
    pose = gtsam.Pose3(gtsam.Rot3.RzRyRx(0.1, -0.2, 0.3), np.array([0.3, -0.1, 0.2]))
    k = gtsam.Cal3_S2(510.0, 495.0, 0.7, 318.0, 242.0)
    point = pose.transformFrom(np.array([0.25, -0.15, 2.0]))
    expected = gtsam.PinholeCameraCal3_S2(pose, k).project(point)
    data = {"point": point[None], "pixel": expected[None]}
    assert np.abs(pixel_residual([pose.matrix()[None], k.vector()[None]], data, False)).max() < 1e-9
    assert np.abs(project(pose, k.vector(), point[None])[0][0] - expected).max() < 1e-9


def test_a_point_behind_the_camera_is_outside_the_model():
    with pytest.raises(ValueError, match="behind the camera"):
        pixel_residual([np.eye(4)[None], np.array([[500.0, 500, 0, 320, 240]])],
                       {"point": np.array([[0.0, 0.0, -1.0]]), "pixel": np.zeros((1, 2))}, False)


def test_intrinsics_from_yaml_values():
    assert CAL3_S2.to_list(CAL3_S2.from_list([500, 490, 0, 320, 240])) == [500.0, 490.0, 0.0, 320.0, 240.0]
    for bad in ([500, 490, 0, 320], [-500, 490, 0, 320, 240]):
        with pytest.raises(ValueError):
            CAL3_S2.from_list(bad)
