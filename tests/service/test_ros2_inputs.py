"""A camera topic's CameraInfo as perceive's intrinsics (arduinobot.service.ros2_inputs):
K and the size as they are, D only for OpenCV's models, none for an uncalibrated camera
(K all zeros), rosbags' CameraInfo messages as a driver fills them."""

from __future__ import annotations

import numpy as np

from arduinobot.service.ros2_inputs import intrinsics_of
from tests.helpers.ros2_publish import T


def _info(k, d=(), model="plumb_bob", size=(640, 480)):
    roi = T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                do_rectify=False)
    return T["sensor_msgs/msg/CameraInfo"](
        header=T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](sec=0,
                                                                               nanosec=0),
                                        frame_id="rgb_camera_link"),
        height=size[1], width=size[0], distortion_model=model, d=np.array(d, float),
        k=np.array(k, float), r=np.eye(3).reshape(-1), p=np.zeros(12), binning_x=0,
        binning_y=0, roi=roi)


def test_k_the_size_and_opencvs_distortion():
    k = [600.0, 0, 319.5, 0, 610.0, 239.5, 0, 0, 1]
    got = intrinsics_of(_info(k, d=[0.1, -0.2, 0.001, 0.002, 0.03]))
    assert got is not None
    assert (got.fx, got.fy, got.cx, got.cy) == (600.0, 610.0, 319.5, 239.5)
    assert (got.width, got.height) == (640, 480)
    assert got.distortion == (0.1, -0.2, 0.001, 0.002, 0.03)
    # a model OpenCV does not take as it is: its D is not passed on as if it were
    fisheye = intrinsics_of(_info(k, d=[0.1, 0.2, 0.3, 0.4], model="equidistant"))
    assert fisheye is not None and fisheye.distortion == ()
    assert intrinsics_of(_info(k, d=[0, 0, 0, 0, 0])).distortion == ()


def test_an_uncalibrated_camera_gives_none():
    assert intrinsics_of(_info([0.0] * 9, d=[])) is None
