"""Scenes and their motion, in millimetres and milliseconds with the camera at the origin
looking down +z.

* :mod:`.motion`: the camera pose, pinhole projection and rigid motion (:class:`Motion`).
* :mod:`.description`: :class:`SceneDescription` (a sensor-free Mitsuba scene dict plus
  motion), loading from a Mitsuba XML file (:func:`load_scene_file`) and moving a loaded
  scene's shapes in time (:class:`SceneAnimator`).
* :mod:`.builtin`: the built-in train set, soccer ball and walker, a PSF generator, and
  :func:`load_scene`, by name or from a file.
* :mod:`.files`: XML and motion JSON export of the built-in scenes.
* :mod:`.layout` (where the built-in scenes' objects stand, the walker's gait), :mod:`.meshes`
  and :mod:`.textures` (their geometry and pictures), and :mod:`.assets`, the cache that
  holds them as files.
* :mod:`.family`: seeded families of scenes (:func:`generate_scene`, :func:`family_scene`),
  also loaded by name, ``family:NAME:SEED``.
* :mod:`.units`: the check, before a capture renders, that a scene is in mm, not metres.

Importing this package does not import Mitsuba; functions that need it import it when called.
"""

from .builtin import (
    BUILTIN_SCENES,
    SCENE_DIR,
    SOCCER_SPEED_PX_PER_MS,
    WALKER_SPEED_MM_PER_MS,
    WHITE_IRRADIANCE,
    load_scene,
    psf_scene,
    soccer_scene,
    train_scene,
    walker_scene,
)
from .description import (
    SceneAnimator,
    SceneDescription,
    fastest_image_speed_px_per_ms,
    is_static,
    load_scene_file,
)
from .family import FAMILIES, family_scene, generate_scene, parse_family_name
from .files import motion_to_json, scene_to_xml, write_scene_files
from .motion import (
    Motion,
    default_camera_to_world,
    image_to_scene_velocity,
    look_at,
    project_px,
)
from .units import check_units

__all__ = [
    "BUILTIN_SCENES",
    "FAMILIES",
    "SCENE_DIR",
    "SOCCER_SPEED_PX_PER_MS",
    "WALKER_SPEED_MM_PER_MS",
    "WHITE_IRRADIANCE",
    "Motion",
    "SceneAnimator",
    "SceneDescription",
    "check_units",
    "default_camera_to_world",
    "family_scene",
    "fastest_image_speed_px_per_ms",
    "generate_scene",
    "image_to_scene_velocity",
    "is_static",
    "load_scene",
    "load_scene_file",
    "look_at",
    "motion_to_json",
    "parse_family_name",
    "project_px",
    "psf_scene",
    "scene_to_xml",
    "soccer_scene",
    "train_scene",
    "walker_scene",
    "write_scene_files",
]
