"""Checkpoints of a moving capture: the finished time steps on disk, so a stopped capture
resumes where it stopped and gives the same image.

A checkpoint is only reused by the capture that wrote it. Its key hashes everything that
changes the image (:func:`resume_parts`): the capture's spec; the loaded scene's every
parameter (geometry, textures and emitters) and every input it was loaded from (an XML's
text, so an attribute ``mi.traverse`` does not show counts too, and every file it names); the
contents of the files the spec names (a schedule); the motions; the integrator; the package,
Mitsuba and Dr.Jit versions and the variant; and the step plan and noise target. Any
difference starts afresh, with a note that names what changed. Every file is written under a
unique temporary name and renamed, and ``state.json``, written last, vouches for the arrays,
which are checked against the capture before they are trusted.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import warnings
from pathlib import Path

import numpy as np

from ..io.lock import output_lock
from ..io.outputs import atomic_save
from ..limits import PacamWarning


def _sha(*chunks: bytes | str) -> str:
    h = hashlib.sha256()
    for c in chunks:
        h.update(c.encode() if isinstance(c, str) else c)
    return h.hexdigest()[:16]


def scene_fingerprint(scene) -> str:
    """A hash of every parameter of a loaded ``mi.Scene`` (``mi.traverse``), before any motion.

    Parameters
    ----------
    scene : mitsuba.Scene

    Returns
    -------
    str
        16 hex digits; about 0.1 s for the 13 MB of the train scene.
    """
    import mitsuba as mi

    params = mi.traverse(scene)
    h = hashlib.sha256()
    for key in sorted(params.keys()):
        value = params[key]
        value = getattr(value, "matrix", value)  # a transform: its matrix
        try:
            a = np.asarray(value)
        except (TypeError, ValueError, RuntimeError):
            a = np.asarray(str(value))
        if a.dtype == object:  # an opaque object: its description
            a = np.asarray(str(value))
        blob = str(a.dtype).encode() + str(a.shape).encode() + a.tobytes()
        h.update(key.encode() + b"\0" + blob)
    return h.hexdigest()[:16]


def resume_parts(spec_key: str, scene, desc, plan, versions: dict, variant: str) -> dict[str, str]:
    """The named hashes that a checkpoint must match to be resumed.

    Parameters
    ----------
    spec_key : str
        The capture's key (:meth:`~pacam_render.exposure.plan.CapturePlan.key`).
    scene : mitsuba.Scene
        Loaded, before any motion is applied.
    desc : SceneDescription
        For its motions.
    plan : JSON-able
        How the passes go: the time steps (pattern, start, end) and the noise target.
    versions : dict
        Package versions, as the record holds them.
    variant : str
        The Mitsuba variant.

    Returns
    -------
    dict
        ``spec``, ``scene``, ``motion``, ``integrator``, ``versions`` and ``steps``, each a hash.
    """
    return {
        "spec": spec_key,
        "scene": _sha(scene_fingerprint(scene), desc.digest()),
        "motion": desc.motion_digest(),
        "integrator": _sha(str(scene.integrator())),
        "versions": _sha(json.dumps({**versions, "variant": variant}, sort_keys=True)),
        "steps": _sha(json.dumps(plan, sort_keys=True)),
    }


class Checkpoint:
    """Finished work kept in ``folder`` (None keeps nothing), for the capture of ``parts``.

    What is kept is a JSON state and named arrays; the caller checks that they fit its capture
    (``check``) before trusting them, so a damaged or tampered checkpoint starts afresh.
    """

    def __init__(self, folder: Path | None, parts: dict[str, str]):
        self.folder, self.parts = folder, dict(parts)
        self.key = _sha(json.dumps(self.parts, sort_keys=True))

    def load(self, check=None) -> tuple[dict, dict[str, np.ndarray]] | None:
        """(state, arrays), or None to start afresh (with a note saying why).

        Parameters
        ----------
        check : callable, optional
            ``check(state, arrays)`` returns None when they fit the capture, else the reason.
        """
        if self.folder is None or not (self.folder / "state.json").is_file():
            return None
        try:
            saved = json.loads((self.folder / "state.json").read_text())
            if saved.get("key") != self.key:
                return self._mismatch(saved.get("parts") or {})
            with np.load(self.folder / "arrays.npz") as z:
                arrays = {k: z[k] for k in z.files}
            state = saved["state"]
            why = check(state, arrays) if check is not None else None
        except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
            return self._afresh(f"cannot be read ({exc})")
        if why:
            return self._afresh(f"does not fit this capture ({why})")
        return state, arrays

    def _mismatch(self, old: dict) -> None:
        changed = [k for k, v in self.parts.items() if old.get(k) != v] or ["its format"]
        return self._afresh(f"holds steps of a different capture ({', '.join(changed)} changed)")

    def _afresh(self, why: str) -> None:
        warnings.warn(f"{self.folder} {why}: starting afresh", PacamWarning, stacklevel=3)
        return None

    def save(self, state: dict, arrays: dict[str, np.ndarray]) -> bool:
        """Write the arrays, then ``state.json``, each under a unique name and renamed.

        Returns False, with a note, when the disk refuses (full, gone read-only): the work in
        memory goes on, and an earlier checkpoint stays whole, since nothing is renamed over
        it unless it was written in full."""
        if self.folder is None:
            return False
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            atomic_save(self.folder / "arrays.npz", lambda t: np.savez(t, **arrays), force=True)
            text = json.dumps({"key": self.key, "parts": self.parts, "state": state})
            atomic_save(self.folder / "state.json", lambda t: Path(t).write_text(text), force=True)
        except OSError as exc:
            warnings.warn(
                f"could not save the finished work to {self.folder} ({exc}); the capture goes "
                "on, but a stop now resumes only from what was saved before",
                PacamWarning,
                stacklevel=2,
            )
            return False
        return True

    def clear(self) -> None:
        if self.folder is not None and self.folder.exists():
            shutil.rmtree(self.folder)


def partial_lock(partial_dir):
    """The lock of the folder that holds ``partial_dir`` (none without one), held while a
    capture writes its checkpoint there (:func:`~pacam_render.io.lock.output_lock`)."""
    if partial_dir is None:
        return contextlib.nullcontext()
    return output_lock(Path(partial_dir).parent)
