"""The values the paper fixes, each written once (Sonoda, Nagahara, Taniguchi 2014).

Table 1 (the prototype) and Section 4 (the experiments). Every other module reads them from
here; a value derived from them (T = 22.5 ms, F9.85, Z_f) is derived, not written again.
"""

from __future__ import annotations

WIDTH_PX = 1280
"""Image width, px (Table 1: Point Grey Grasshopper, Sony ICX285)."""
HEIGHT_PX = 960
"""Image height, px (Table 1)."""
FOV_DEG = 46.0
"""Horizontal field of view, deg (Table 1)."""
PIXEL_PITCH_MM = 0.00645
"""ICX285 pixel pitch, mm (6.45 um)."""
F_MIN = 2.8
"""The lens's F-number with the whole LCoS disc open (Table 1)."""
LCOS_DISC_PX = 512
"""The full opening: a disc of 512 LCoS pixels' radius, half the display's height (F2.8)."""
OPENING_LCOS_PX = 145.5
"""Section 4's opening radius in LCoS pixels (F9.85 on the paper's scale)."""
EXPOSURE_MS = 45.0
"""The exposure 2T, ms: 16 patterns at 365 fps (Section 4)."""
LCOS_RATE_FPS = 365.0
"""Patterns the LCoS shows per second (Table 1)."""
N_PATTERNS = 16
"""Aperture patterns shown during one exposure (Section 4)."""
SHORT_EXPOSURE_MS = 0.679
"""The short exposure compared with, ms, taken at F2.8 (Section 3.3, Fig. 8)."""
OBJECT_DEPTH_MM = 500.0
"""Depth of the objects in the train experiment, mm (Section 4)."""
STATIC_R_PX = 2.0
"""The static PSF radius r at the object, px (Section 4)."""
