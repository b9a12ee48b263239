"""The small train store the rendered-search tests share (tests/optimize/conftest.py renders it
once per session)."""

from pacam_render.exposure.spec import CaptureSpec

SPEC = CaptureSpec.geometric(scene="train", width=1280, height=960, crop=(440, 400, 96, 64),
                             mode="coded", spp=4, passes=2, seed=3)  # fmt: skip
"""A 96x64 window of the near train, 4 spp in 2 passes: enough for the prototype's kernel."""
