"""Variant selection, including the fallback path. Each case runs in a fresh interpreter because
drjit fixes its libLLVM at first import (and a bad one would abort the test process)."""

import glob
import os
import subprocess
import sys

import pytest

SNIPPET = """
import warnings
warnings.simplefilter("always")
from pacam_render.render.backend import select_variant
from pacam_render.render.variant import BackendWarning
with warnings.catch_warnings(record=True) as caught:
    v = select_variant(mono={mono})
    select_variant(mono={mono})  # a second request must not warn again
n = sum(issubclass(w.category, BackendWarning) for w in caught)
print(v, n)
"""


def run(env_extra: dict, mono: bool = False) -> tuple[str, int, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PACAM_VARIANT", "DRJIT_LIBLLVM_PATH")}
    env.update(env_extra)
    out = subprocess.run(
        [sys.executable, "-c", SNIPPET.format(mono=mono)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    name, n = out.stdout.split()
    return name, int(n), out.stderr


def test_missing_libllvm_falls_back_to_scalar_with_one_warning():
    name, n, _ = run({"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so"})
    assert name == "scalar_rgb" and n == 1


def test_mono_request_on_scalar_uses_rgb():
    """The Mitsuba wheel has no scalar_mono: the fallback is still a variant that exists."""
    name, _, _ = run({"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so"}, mono=True)
    assert name == "scalar_rgb"


def test_mono_request_gives_mono_variant():
    from pacam_render.render.variant import llvm_status

    if not llvm_status()[0]:
        pytest.skip("LLVM backend not available here")
    name, _, _ = run({}, mono=True)
    assert name == "llvm_ad_mono"


@pytest.mark.skipif(not glob.glob("/usr/lib/*/libLLVM-15.so*"), reason="needs Debian's libLLVM-15")
def test_too_old_libllvm_is_refused_not_crashed():
    """libLLVM-15 loads but aborts renders: it must be detected before any render."""
    lib = sorted(glob.glob("/usr/lib/*/libLLVM-15.so*"))[0]
    name, n, _ = run({"DRJIT_LIBLLVM_PATH": lib})
    assert name == "scalar_rgb" and n == 1


def test_environment_override():
    name, n, _ = run({"PACAM_VARIANT": "scalar_spectral"})
    assert name == "scalar_spectral" and n == 0


def test_bad_override_is_a_clear_error():
    env = dict(os.environ, PACAM_VARIANT="nonsense_variant")
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "from pacam_render.render.backend import select_variant; select_variant()",
        ],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode != 0
    assert "PACAM_VARIANT='nonsense_variant' is not a Mitsuba variant" in out.stderr


def test_llvm_is_chosen_when_it_works():
    from pacam_render.render.variant import llvm_status

    ok, why = llvm_status()
    if not ok:
        pytest.skip(f"LLVM backend not available here: {why}")
    name, n, _ = run({})
    assert name == "llvm_ad_rgb" and n == 0


@pytest.mark.parametrize("command", ["render", "study"])
def test_cuda_override_without_a_gpu_is_a_one_line_refusal(command, tmp_path):
    """PACAM_VARIANT=cuda_ad_rgb where CUDA does not load: exit 2, one line naming the CPU
    variant to use instead, no traceback and no output folder (issue 35); a study refuses it
    once, before any point, not once per point."""
    probe = "from pacam_render.render.variant import cuda_available; print(cuda_available())"
    env = {k: v for k, v in os.environ.items() if k != "PACAM_VARIANT"}
    has_gpu = subprocess.run(
        [sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120
    )
    if has_gpu.stdout.strip() == "True":
        pytest.skip("CUDA loads here: the refusal is for machines without a GPU")
    out = tmp_path / "gpu"
    if command == "render":
        args = ["train", "--width", "32", "--height", "24", "--spp", "4"]
    else:
        spec = tmp_path / "tiny.toml"
        spec.write_text(
            "[render]\nwidth = 32\nheight = 24\nnoise_ratio = false\nspp = 4\n"
            '[grid]\nmethod = ["none"]\n'
        )
        args = [str(spec), "--workers", "0", "--quiet"]
    done = subprocess.run(
        [sys.executable, "-m", "pacam_render", command, *args, "--out", str(out)],
        env={**env, "PACAM_VARIANT": "cuda_ad_rgb"},
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith(f"pacam {command}: error: PACAM_VARIANT='cuda_ad_rgb' cannot render")
    assert "PACAM_VARIANT=llvm_ad_rgb" in lines[0] and "unset PACAM_VARIANT" in lines[0]
    assert not out.exists()
