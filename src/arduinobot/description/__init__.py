"""The arduinobot description, and any user's URDF/xacro, loaded without ROS."""

import logging

from arduinobot.description.errors import (
    DescriptionError,
    InvalidModel,
    MalformedXml,
    MeshLoadError,
    MeshNotFound,
    MissingXacroArgument,
    PackageNotFound,
    SrdfError,
    XacroError,
)
from arduinobot.description.loader import (
    DEFAULT_MODEL,
    Description,
    Tcp,
    load_description,
    read_model_text,
)
from arduinobot.description.model import (
    Geometry,
    Inertial,
    Joint,
    Limit,
    Link,
    Mimic,
    Origin,
    Robot,
    Shape,
)
from arduinobot.description.packages import PackageIndex, build_package_index
from arduinobot.description.srdf import Srdf

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "DEFAULT_MODEL", "Description", "DescriptionError", "Geometry", "Inertial", "InvalidModel",
    "Joint", "Limit", "Link", "MalformedXml", "MeshLoadError", "MeshNotFound", "Mimic",
    "MissingXacroArgument", "Origin", "PackageIndex", "PackageNotFound", "Robot", "Shape",
    "Srdf", "SrdfError", "Tcp", "XacroError", "build_package_index", "load_description",
    "read_model_text",
]
