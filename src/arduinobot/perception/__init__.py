"""See objects: camera images to scene objects through markers (issue 41).

Imported by the service and the command line only, never by the core; OpenCV (and MuJoCo
for the twin's camera) are the optional ``see`` extra, imported inside the functions
that need them.

- ``errors``: what an image could not give (IMAGE_INVALID, NO_MARKER, UNKNOWN_MARKER,
  MARKER_REFUSED).
- ``intrinsics``: a camera's pinhole model, from a ROS camera_info YAML or the URDF's
  Gazebo camera sensor.
- ``markers``: the map of marker ids to objects (objects.yaml, a request's ``markers``).
- ``camera``: the camera's optical frame in the world, from the model's FK at a state.
- ``image``: PNG/JPEG bytes decoded and checked.
- ``raw_image``: uncompressed pixels (a ROS ``sensor_msgs/msg/Image``) to grey, and a
  topic's latest image (``CapturedImage``).
- ``detect``: markers found in an image and their poses in the optical frame.
- ``locate``: markers to objects in the world, uncertainty and padding (``perceive``).
- ``twin_view``: MuJoCo renders the camera's view with the markers as textures.
"""
