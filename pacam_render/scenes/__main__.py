"""``python -m pacam_render.scenes --write [DIR]``: regenerate the scene XML and motion files."""

import sys

from .files import write_scene_files

if sys.argv[1:2] == ["--write"]:
    for p in write_scene_files(*sys.argv[2:3]):
        print(p)
else:
    print("usage: python -m pacam_render.scenes --write [DIR]")
