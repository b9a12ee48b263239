"""Files in and out: multi-layer float32 OpenEXR (:mod:`.exr`), 8-bit sRGB PNG previews
(:mod:`.preview`), and JSON, text and output folders (:mod:`.outputs`). Every file is written
atomically (a temporary file, then a rename), an existing file is replaced only when forced,
and reading a missing or corrupt EXR file (or a missing layer) is a clear
:class:`~pacam_render.errors.ParameterError`.
"""
