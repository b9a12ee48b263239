"""What the rendering commands (``render``, ``validate``, ``sensor``) share beyond
:mod:`..common`: the optics flags (:mod:`.optics_flags`) and a capture's output lines and
files (:mod:`.capture_out`)."""
