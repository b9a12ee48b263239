"""The package's shape: no import cycles between its files, light import, plugin registration
across variants, one table of modes, and the typed capture record."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import pytest

import pacam_render
from pacam_render.capture.record import CaptureRecord, SensorRecord
from pacam_render.errors import ParameterError
from pacam_render.exposure.camera import mode_camera
from pacam_render.exposure.spec import CaptureSpec
from pacam_render.model import paper
from pacam_render.model.camera import prototype
from pacam_render.model.modes import MODES, MODES_WITH_PSF, capture_camera, mode, t0_offset_px
from pacam_render.psf.analytic import design_psf
from pacam_render.psf_render.mode_setup import RENDER_MODES, mode_setup

PACKAGE = Path(pacam_render.__file__).resolve().parent

ALLOWED_CYCLES: dict[str, set[str]] = {}
"""Import cycles the test tolerates, each a set of modules; a cycle among other modules fails."""


def _modules() -> dict[str, Path]:
    """Every file of the package by dotted name (a package's own file as ``pkg.__init__``)."""
    root = PACKAGE.parent
    return {".".join(p.relative_to(root).with_suffix("").parts): p for p in PACKAGE.rglob("*.py")}


def _targets(name: str, node: ast.Import | ast.ImportFrom, mods: dict) -> list[str]:
    """The files an import statement in module ``name`` names (a module, else its package)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    target = node.module or ""
    if node.level:  # relative: from the module's package (a package's __init__ is in it too)
        package = name.split(".")[:-1]
        target = ".".join(package[: len(package) - node.level + 1] + ([target] if target else []))
    return [f"{target}.{a.name}" if f"{target}.{a.name}" in mods else target for a in node.names]


def import_graph() -> dict[str, set[str]]:
    """The package's file-level import graph: module-level and function-level imports (and those
    under ``TYPE_CHECKING``) alike; package ``__init__`` files (re-exports) and ``__main__`` left
    out, as ``house_check.py`` counts them."""
    mods = _modules()
    graph = {m: set() for m in mods if not m.endswith(("__init__", "__main__"))}
    for m in graph:
        for node in ast.walk(ast.parse(mods[m].read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                graph[m].update(t for t in _targets(m, node, mods) if t in graph and t != m)
    return graph


def import_cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = {stack.pop()}
            while v not in comp:
                comp.add(stack.pop())
            if len(comp) > 1:
                cycles.append(comp)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


def test_the_import_graph_counts_function_level_imports():
    graph = import_graph()
    assert "pacam_render.render.registry" in graph["pacam_render.exposure.direct"]  # module level
    assert "pacam_render.render.backend" in graph["pacam_render.scenes.motion"]  # in _mi()
    assert "pacam_render.render.__init__" not in graph  # package files are left out
    assert import_cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]


def inner_imports() -> list[tuple[str, int, bool]]:
    """(module, line, says why) of every import of the package's own modules inside a function
    body; it says why when a comment stands on its line or the line above."""
    out = []
    for name, path in _modules().items():
        lines = path.read_text().split("\n")
        tree = ast.parse("\n".join(lines))
        for fn in ast.walk(tree):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                own = isinstance(node, ast.ImportFrom) and (
                    node.level or (node.module or "").startswith("pacam_render")
                ) or isinstance(node, ast.Import) and any(
                    a.name.startswith("pacam_render") for a in node.names
                )  # fmt: skip
                if own:
                    here = lines[node.lineno - 1] + lines[node.lineno - 2]
                    out.append((name, node.lineno, "#" in here))
    return out


def test_the_package_imports_its_own_modules_at_the_top():
    """Imports of the package's own modules sit at the top of each module (issue 55 item 5); one
    inside a function says why (a cycle, a measured import cost) in a comment beside it."""
    silent = [f"{m}:{line}" for m, line, why in inner_imports() if not why]
    assert not silent, f"inner imports that do not say why: {silent}"
    assert len({(m, line) for m, line, _ in inner_imports()}) == len(inner_imports())


def test_the_inner_import_check_finds_one(tmp_path, monkeypatch):
    """The check above sees a silent inner import (it can fail)."""
    (tmp_path / "pacam_render").mkdir()
    (tmp_path / "pacam_render" / "m.py").write_text("def f():\n    from . import x\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", tmp_path / "pacam_render")
    assert inner_imports() == [("pacam_render.m", 2, False)]


MAX_MODULES = 16
"""The most modules (``__init__`` included) one folder of the package may hold (issue 55)."""


def test_no_folder_holds_more_than_16_modules():
    """Modules are grouped by what they make: a folder past 16 is split (render/kernels/ and
    exposure/optics/ were)."""
    folders = {p.parent for p in PACKAGE.rglob("*.py")}
    sizes = {str(f.relative_to(PACKAGE.parent)): len(list(f.glob("*.py"))) for f in folders}
    assert max(sizes.values()) <= MAX_MODULES, {f: n for f, n in sizes.items() if n > MAX_MODULES}


def test_no_import_cycles_between_files():
    """No file of the package imports, at any level, a file that imports it back, except the
    cycles of :data:`ALLOWED_CYCLES` (a smaller cycle among the same modules is allowed too)."""
    cycles = import_cycles(import_graph())
    new = [c for c in cycles if not any(c <= allowed for allowed in ALLOWED_CYCLES.values())]
    assert not new, "import cycles: " + "; ".join(" <-> ".join(sorted(c)) for c in new)


def test_the_allowed_cycles_still_exist():
    """An entry of :data:`ALLOWED_CYCLES` whose cycle is gone must be removed."""
    cycles = import_cycles(import_graph())
    gone = [k for k, allowed in ALLOWED_CYCLES.items() if not any(c <= allowed for c in cycles)]
    assert not gone, f"no cycle left in ALLOWED_CYCLES {gone}: remove the entries"


def _python(code: str) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip()


def test_import_is_light_and_the_plugin_registers_on_first_use():
    code = (
        "import sys, pacam_render as pr\n"
        "print(sorted(m for m in ('mitsuba', 'drjit') if m in sys.modules))\n"
        "pr.select_variant()\n"
        "import mitsuba as mi\n"
        "s = mi.load_dict(pr.sensor_dict(lens_radius=5.0, fov=40))\n"
        "print(type(s).__name__)\n"
    )
    lines = _python(code).splitlines()
    assert lines[0] == "[]"
    assert lines[-1] == "ProgrammableApertureCamera"


def test_both_plugins_follow_variant_switches():
    """After a switch to scalar_rgb and back, both sensors load again (module re-import)."""
    code = (
        "from pacam_render import render\n"
        "import mitsuba as mi\n"
        "v = render.select_variant()\n"
        "for variant in ('scalar_rgb', v):\n"
        "    mi.set_variant(variant)\n"
        "    for plugin in (render.PLUGIN_NAME, render.PSF_PLUGIN_NAME):\n"
        "        d = render.sensor_dict(lens_radius=5.0, fov=40)\n"
        "        d['type'] = plugin\n"
        "        s = mi.load_dict(d)\n"
        "        print(variant, type(s).__name__, isinstance(s, mi.Sensor))\n"
    )
    lines = _python(code).splitlines()
    assert [ln.split()[1:] for ln in lines] == [
        ["ProgrammableApertureCamera", "True"],
        ["PSFCamera", "True"],
    ] * 2
    assert lines[0].startswith("scalar_rgb")


def test_every_mode_is_in_the_one_table():
    assert [CaptureSpec(mode=m).mode for m in MODES] == list(MODES)  # captures take them all
    with pytest.raises(ParameterError, match="valid: normal, coded"):
        CaptureSpec(mode="blurry")
    assert set(RENDER_MODES) == set(MODES_WITH_PSF) == {m for m in MODES if MODES[m].psf}
    assert "reference" in MODES and "reference" not in MODES_WITH_PSF
    with pytest.raises(ParameterError, match="valid: normal, coded"):
        mode("blurry")
    with pytest.raises(ParameterError, match="valid"):
        design_psf(prototype(), "reference")


@pytest.mark.parametrize("name", MODES_WITH_PSF)
def test_capture_and_psf_render_configure_the_same_sensor(name):
    """The capture of a mode and the PSF rendering of its camera show the same schedule."""
    design = prototype()
    cam, params = mode_camera(design, name)
    setup = mode_setup(cam, name)
    assert setup.sensor == params
    assert setup.exposure_ms == cam.exposure_ms
    assert setup.origin_px == pytest.approx(t0_offset_px(cam, name))


def test_mode_policies_against_the_paper():
    design = prototype()
    short = capture_camera(design, "short")
    assert short.exposure_ms == paper.SHORT_EXPOSURE_MS
    assert short.F_number == pytest.approx(paper.F_MIN)  # the whole lens open
    assert short.r_px == pytest.approx(0.0, abs=1e-9)  # focused on the object
    normal = capture_camera(design, "normal")
    assert normal.R_mm == design.R_mm and normal.r_px == pytest.approx(0.0, abs=1e-9)
    assert capture_camera(design, "coded") == design == capture_camera(design, "levin")
    assert mode_camera(design, "levin")[1]["focus_distance"] == design.object_depth_mm
    # the t = 0 image offset is -beta (R_max - R) = -a_i T^2 / 4 (Eqs. 10, 17)
    beta_travel = -design.beta_px_per_mm * (design.R_max_mm - design.R_mm)
    assert t0_offset_px(design, "coded") == pytest.approx(beta_travel, rel=1e-9)
    assert t0_offset_px(design, "normal") == 0.0
    # the short kernel is a box of |s| x 0.679 ms
    k = design_psf(short, "short", 10.0, size=(1, 15))
    assert 1.0 / k.max() == pytest.approx(10.0 * paper.SHORT_EXPOSURE_MS)  # 1/L per full px


def _record(**over) -> CaptureRecord:
    base = dict(
        spec={"mode": "coded"},
        mode="coded",
        camera=prototype().inputs(),
        optics={},
        coded_design={},
        sensor_params={},
        exposure_ms=45.0,
        reference_exposure_ms=45.0,
        light_factor=0.25,
        render_seconds=1.0,
        variant="llvm_ad_rgb",
        versions={},
    )
    return CaptureRecord(**{**base, **over})


def test_record_round_trips_through_json():
    rec = _record(
        sensor=SensorRecord("paper", {"qe": 1.0}, None, 1.5, 3),
        noise_sigma=0.005,
        resumed_from_step=4,
    )
    d = json.loads(json.dumps(rec.to_json()))
    assert d["noise_sigma"] == 0.005 and d["noise_sigma_unit"].startswith("radiance x")
    assert "noise_sigma_white_units" not in d["sensor"]  # one noise sigma, in one unit
    assert "fastest_image_speed_px_per_ms" not in d  # unset optional fields are left out
    back = CaptureRecord.from_json(d)
    assert back == rec
    assert back.known_noise_sigma == 0.005


def test_record_writes_a_repeated_design_once_and_reads_both_forms():
    """capture.json holds each value once (issue 27 item 7): a coded capture's optics are its
    coded design, so coded_design is left out and read back as optics; a normal capture's
    camera differs from the design in a few values, which are all coded_design keeps; older
    files with both full blocks still read."""
    coded = prototype().summary()
    full = prototype().with_(R_mm=prototype().R_max_mm)
    normal = full.summary()
    rec = _record(optics=coded, coded_design=dict(coded))
    d = json.loads(json.dumps(rec.to_json()))
    assert "coded_design" not in d and d["optics"] == coded
    assert CaptureRecord.from_json(d) == rec
    assert CaptureRecord.from_json({**d, "coded_design": dict(coded)}) == rec  # older files
    assert rec.to_json(compact=False)["coded_design"] == coded
    # the record's camera is the normal capture's (its digest is the optics')
    other = _record(mode="normal", camera=full.inputs(), optics=normal, coded_design=coded)
    d = json.loads(json.dumps(other.to_json()))
    assert d["optics"] == normal
    assert d["coded_design"] == {k: v for k, v in coded.items() if normal[k] != v} != {}
    assert CaptureRecord.from_json(d) == other
    assert CaptureRecord.from_json({**d, "coded_design": coded}) == other  # older files


def test_record_reads_the_older_demo_sensor_block():
    d = _record().to_json()
    d["sensor"] = {"preset": "grasshopper-icx285", "light_level": 300.0, "seed": 0,
                   "photons_per_unit": 2.0, "noise_sigma_white_units": 0.04}  # fmt: skip
    d["future_key"] = [1, 2]
    rec = CaptureRecord.from_json(d)
    assert rec.sensor.light_level_photons_per_px_per_ms == 300.0
    assert rec.known_noise_sigma == pytest.approx(0.04 * 0.25)  # white units x light factor
    assert rec.noise_sigma_white_units == pytest.approx(0.04)
    assert rec.to_json()["future_key"] == [1, 2]  # unknown keys are kept


def test_record_without_camera_is_a_clear_error():
    with pytest.raises(ParameterError, match="lacks 'camera'"):
        CaptureRecord.from_json({"mode": "coded"}, where="x.json")
    with pytest.raises(ParameterError, match="JSON object"):
        CaptureRecord.from_json([1, 2], where="x.json")


WAVE_MAY_IMPORT = ("pacam_render.errors", "pacam_render.limits", "pacam_render.model")
"""The package modules that :mod:`pacam_render.wave` (pupils and diffraction) may import."""


def test_wave_is_a_numpy_only_leaf_below_psf():
    """``wave/`` sits between ``model/`` and ``psf/``: it imports numpy, the standard library
    and the modules of :data:`WAVE_MAY_IMPORT` only, and nothing below it imports ``psf/``,
    ``render/`` or Mitsuba."""
    mods = _modules()
    for name, path in mods.items():
        if not name.startswith("pacam_render.wave."):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for target in _targets(name, node, mods):
                    top = target.split(".")[0]
                    if top == "pacam_render":
                        inside = target.startswith(("pacam_render.wave", *WAVE_MAY_IMPORT))
                        assert inside, f"{name} imports {target}"
                    else:
                        assert top in ("numpy", "__future__") or top in sys.stdlib_module_names, (
                            f"{name} imports {target}"
                        )


LAYERS = (
    "errors",
    "lazy",
    "limits",
    "io",
    "model",
    "wave",
    "psf",
    "render",
    "scenes",
    "capture",
    "sensor",
    "restore",
    "exposure",
    "psf_render",
    "lightfield",
    "optimize",
    "study",
    "dataset",
    "experiments",
    "cli",
)
"""The subpackages (and top-level modules) from the bottom up: a file imports only from its own
floor or below. ``capture/`` (the record) sits below its readers (``sensor/``, ``restore/``,
``study/``, the CLI) and its producers (``exposure/``)."""


def _floor(module: str) -> str:
    return module.split(".")[1]


def climbs(graph: dict[str, set[str]]) -> list[str]:
    """Every import that runs back up :data:`LAYERS`, as ``importer -> imported``."""
    rank = {name: i for i, name in enumerate(LAYERS)}
    return sorted(
        f"{m} -> {t}"
        for m, targets in graph.items()
        for t in targets
        if rank[_floor(t)] > rank[_floor(m)]
    )


def test_every_subpackage_has_a_floor():
    floors = {_floor(m) for m in import_graph()}
    assert floors == set(LAYERS), f"place {sorted(floors - set(LAYERS))} in LAYERS"


def test_no_import_climbs_back_up_the_subpackages():
    """No file imports (at any level) from a subpackage above its own: the record is read by
    ``restore/`` and ``sensor/`` without reaching into ``exposure/``."""
    assert climbs({"a.restore.x": {"a.exposure.y"}, "a.exposure.y": {"a.capture.z"}}) == [
        "a.restore.x -> a.exposure.y"
    ]  # the check itself sees a climb
    assert climbs(import_graph()) == []
