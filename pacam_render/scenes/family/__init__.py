"""Seeded families of scenes: textured objects in front of a textured wall, drawn from a seed
and written as files every command reads (``scene.xml``, ``scene.motion.json``) plus a card
(``scene.json``).

* :mod:`.spec`: the families (:data:`FAMILIES`), their parameters and checks, and scene names
  ``family:NAME:SEED`` (:func:`parse_family_name`).
* :mod:`.draw`: the seeded drawing of the objects.
* :mod:`.occlusion`: which object passes in front of which, inside the window.
* :mod:`.textures`: procedural and photographic textures.
* :mod:`.write`: the files and the card (:func:`generate_scene`), and the cache
  (:func:`family_scene`).

Importing this package does not import Mitsuba.
"""

from .draw import SHAPES, FamilyObject
from .spec import FAMILIES, FAMILY_VERSION, family_seeds, parse_family_name, resolve_params
from .textures import PHOTOS
from .write import family_scene, generate_scene

__all__ = [
    "FAMILIES",
    "FAMILY_VERSION",
    "PHOTOS",
    "SHAPES",
    "FamilyObject",
    "family_scene",
    "generate_scene",
    "family_seeds",
    "parse_family_name",
    "resolve_params",
]
