"""Resuming a study folder with an edited spec: each row's ``point_key`` says which point of the
new spec it is; rows of no point are set aside in a backup, never lost, and a folder written
before rows had keys resumes only for the same spec, as before."""

from __future__ import annotations

import csv
import json
import warnings
from dataclasses import replace

import pytest

from pacam_render.errors import ParameterError
from pacam_render.limits import PacamWarning
from pacam_render.study import load_study, run_study
from pacam_render.study.point import COLUMNS, point_row, render_target
from pacam_render.study.results import RESULTS, STUDY, Results, row_digest

TINY = """
[study]
name = "tiny"
report = "crossover"
[render]
width = 48
height = 36
spp = 4
max_step_px = 4.0
noise_ratio = {ratio}
[grid]
mode = ["coded", "short"]
light_level = {levels}
"""


def _spec(tmp_path, levels="[30.0, 3000.0]", ratio="false", extra="", name="tiny.toml"):
    path = tmp_path / name
    path.write_text(TINY.format(levels=levels, ratio=ratio) + extra)
    return load_study(str(path))


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _values(p) -> tuple:
    return (p.mode, p.light_level)


def _fake_run(out, spec) -> dict[tuple, dict]:
    """A folder as a finished run leaves it, each row's score made from its point's values
    (so that a row can be told from another without rendering)."""
    results = Results(out, spec)
    names = ("psnr_db", "psnr_moving_db", "psnr_static_db", "ssim", "noise_sigma")
    score = {p.index: dict.fromkeys(names, p.light_level + len(p.mode)) for p in spec.points}
    for values in score.values():
        values.update(speed_px_per_ms=0.7, depth_mm=1000.0)
    results.add([point_row(p, score[p.index], "ok", 1.0, 2.0) for p in spec.points])
    return {_values(p): r for p, r in zip(spec.points, _rows(out / RESULTS))}


def _resume(out, spec) -> tuple[Results, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PacamWarning)
        results = Results(out, spec)
    return results, [str(w.message) for w in caught if issubclass(w.category, PacamWarning)]


# --- the point keys ------------------------------------------------------------------------------
def test_a_point_key_ignores_the_index_and_follows_what_reaches_the_row(tmp_path):
    a = _spec(tmp_path)
    b = _spec(tmp_path, "[10.0, 30.0]")  # 3000 removed, 10 added: the 30s renumbered
    ka = {_values(p): a.point_keys()[p.index] for p in a.points}
    kb = {_values(p): b.point_keys()[p.index] for p in b.points}
    assert [p.index for p in b.points if p.light_level == 30.0] == [1, 3]  # were 0 and 2
    assert ka[("coded", 30.0)] == kb[("coded", 30.0)] and ka[("short", 30.0)] == kb[("short", 30.0)]
    assert len(set(ka.values())) == len(ka) and len(set(kb.values())) == len(kb)
    edits = [("spp = 4", "spp = 5"), ("max_step_px = 4.0", "max_step_px = 3.0"), ("48", "40")]
    edits.append(("[grid]", "crop = [0, 0, 24, 18]\n[grid]"))
    for was, now in edits:
        path = tmp_path / "changed.toml"
        path.write_text(TINY.replace(was, now).format(levels="[30.0, 3000.0]", ratio="false"))
        other = load_study(str(path))
        assert not set(other.point_keys().values()) & set(ka.values()), now
    renamed = _spec(tmp_path, name="renamed.toml")
    assert renamed.point_keys() == a.point_keys()  # the file's name is no input
    assert not set(replace(a, decompose=True).point_keys().values()) & set(ka.values())


def test_with_a_noise_target_a_key_follows_every_sensor_of_its_render(tmp_path):
    """A render is rendered to the lowest noise among the points it feeds, so a light level
    added to the coded render changes every coded point's render and key; the short render's
    points keep theirs."""
    a = _spec(tmp_path, "[30.0]", ratio="0.2")
    extra = '\n[[points]]\nmode = "coded"\nlight_level = 3000.0\n'
    b = _spec(tmp_path, "[30.0]", ratio="0.2", extra=extra, name="b.toml")
    ka = {_values(p): a.point_keys()[p.index] for p in a.points}
    kb = {_values(p): b.point_keys()[p.index] for p in b.points}
    assert ka[("short", 30.0)] == kb[("short", 30.0)]
    assert ka[("coded", 30.0)] != kb[("coded", 30.0)]
    coded = [g for g in b.groups() if g[0].mode == "coded"][0]
    sensor = b.render["sensor"]
    assert render_target(b.render, coded).sensors == ((sensor, 30.0), (sensor, 3000.0))


# --- the folder ----------------------------------------------------------------------------------
def test_an_edited_spec_keeps_matching_rows_renumbered_and_sets_the_rest_aside(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    old = _fake_run(out, _spec(tmp_path))
    before = (out / RESULTS).read_bytes()
    (out / "images" / "render_0000").mkdir(parents=True)
    new = _spec(tmp_path, "[10.0, 30.0]")
    results, notes = _resume(out, new)
    assert results.done() == {1, 3} and results.set_aside == 2
    now = {int(r["point"]): r for r in _rows(out / RESULTS)}
    assert sorted(now) == [1, 3]
    for p in new.points:
        if p.light_level == 30.0:  # the old row, renumbered, every other column as it was
            row = {**old[_values(p)], "point": str(p.index)}
            assert {**now[p.index], "row_digest": ""} == {**row, "row_digest": ""}
            assert now[p.index]["row_digest"] == row_digest(row)  # its digest follows the number
    backup = out / "results.before-{}.csv".format(json.loads((out / STUDY).read_text())["key"])
    assert not backup.exists()  # study.json now names the new spec: the backup is the old one's
    (backup,) = out.glob("results.before-*.csv")
    assert backup.read_bytes() == before
    assert not (out / "images").exists() and (out / f"images.before-{backup.stem[15:]}").is_dir()
    assert len(notes) == 1
    assert "2 points kept" in notes[0] and "2 to run, 2 old rows set aside" in notes[0]
    assert str(backup) in notes[0]


def test_a_changed_render_setting_keeps_nothing_and_loses_nothing(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    _fake_run(out, _spec(tmp_path))
    before = (out / RESULTS).read_bytes()
    path = tmp_path / "crop.toml"
    text = TINY.replace("[grid]", "crop = [0, 0, 24, 18]\n[grid]")
    path.write_text(text.format(levels="[30.0, 3000.0]", ratio="false"))
    results, notes = _resume(out, load_study(str(path)))
    assert results.done() == set() and results.set_aside == 4 and _rows(out / RESULTS) == []
    assert results.backup.read_bytes() == before and "0 points kept" in notes[0]
    # a second edit keeps the first backup and writes another beside it
    _fake_run(out, load_study(str(path)))
    again = tmp_path / "spp.toml"
    again.write_text(path.read_text().replace("spp = 4", "spp = 5"))
    second, _ = _resume(out, load_study(str(again)))
    assert second.backup != results.backup and results.backup.read_bytes() == before


def test_the_same_spec_resumes_quietly_and_force_starts_afresh(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    spec = _spec(tmp_path)
    _fake_run(out, spec)
    before = (out / RESULTS).read_bytes()
    results, notes = _resume(out, spec)
    assert results.done() == {0, 1, 2, 3} and notes == [] and (out / RESULTS).read_bytes() == before
    forced = Results(out, _spec(tmp_path, "[10.0]"), force=True)
    assert forced.done() == set() and _rows(out / RESULTS) == []


def _legacy(out, spec) -> None:
    """A folder as written before rows had keys: no point_key column (nor row_digest)."""
    _fake_run(out, spec)
    rows = _rows(out / RESULTS)
    old_columns = [c for c in COLUMNS if c not in ("point_key", "row_digest")]
    with open(out / RESULTS, "w", newline="") as f:
        writer = csv.DictWriter(f, old_columns, extrasaction="ignore", lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)


def test_a_folder_without_point_keys_resumes_only_for_the_same_spec(tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    spec = _spec(tmp_path)
    _legacy(out, spec)
    before = (out / RESULTS).read_bytes()
    with pytest.raises(ParameterError, match=r"holds results of another study \('tiny', or"):
        Results(out, _spec(tmp_path, "[10.0, 30.0]"))
    assert (out / RESULTS).read_bytes() == before and not list(out.glob("results.before-*"))
    results, notes = _resume(out, spec)  # the same spec: resumed, and its rows get their keys
    assert results.done() == {0, 1, 2, 3} and notes == []
    keys = spec.point_keys()
    assert [r["point_key"] for r in _rows(out / RESULTS)] == [keys[k] for k in range(4)]


def test_cli_names_flags_in_the_resume_note_and_the_legacy_refusal(tmp_path, capsys):
    from pacam_render.cli import main

    out = tmp_path / "o"
    out.mkdir()
    _fake_run(out, _spec(tmp_path))
    _spec(tmp_path, "[30.0]")  # one level removed: both remaining points kept, nothing to render
    argv = ["study", str(tmp_path / "tiny.toml"), "--out", str(out), "--workers", "0", "--quiet"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "0 points run, 2 already done" in captured.out
    (note,) = [line for line in captured.err.splitlines() if "note:" in line]
    assert f"--out {out} holds results of another spec: 2 points kept" in note
    assert "(--force starts afresh)" in note and "`" not in note
    legacy = tmp_path / "legacy"
    legacy.mkdir()
    _legacy(legacy, _spec(tmp_path, name="l.toml"))
    argv[2:4] = ["--out", str(legacy)]
    assert main(argv) == 2
    assert "pass --force to start afresh there, or choose another --out" in capsys.readouterr().err


def test_a_render_for_the_points_left_is_rendered_to_its_whole_groups_target(tmp_path):
    from pacam_render.study import _tasks

    spec = _spec(tmp_path, "[30.0, 3000.0]", ratio="0.2")
    done = {p.index for p in spec.points if p.light_level == 3000.0}
    tasks = _tasks(spec, done, tmp_path, False)
    assert [len(t.points) for t in tasks] == [1, 1]
    whole = render_target(spec.render, spec.points).sensors
    assert [render_target(t.render, t.group).sensors for t in tasks] == [whole, whole]


# --- a rendered study ----------------------------------------------------------------------------
@pytest.mark.render
def test_an_edited_study_renders_only_its_new_points_and_equals_a_fresh_run(tmp_path, monkeypatch):
    """3000 removed and 10 added: the 30 rows are kept byte for byte (renumbered), only the
    two 10 points render (one render per mode), and the folder then holds what a fresh run
    of the edited spec writes, timings aside."""
    import pacam_render.study.point as P

    out = tmp_path / "o"
    run_study(_spec(tmp_path), out, workers=0, progress=False)
    level = "light_level_photons_per_px_per_ms"
    old = {(r["mode"], float(r[level])): r for r in _rows(out / RESULTS)}
    before = (out / RESULTS).read_bytes()
    real, rendered = P._render, []

    def counted(task):
        rendered.append(tuple(_values(p) for p in task.points))
        return real(task)

    monkeypatch.setattr(P, "_render", counted)
    new = _spec(tmp_path, "[10.0, 30.0]")
    with pytest.warns(PacamWarning, match="2 points kept .* 2 to run, 2 old rows set aside"):
        s = run_study(new, out, workers=0, progress=False)
    assert (s.skipped, s.ran, s.failed, s.set_aside) == (2, 2, 0, 2)
    assert sorted(rendered) == [(("coded", 10.0),), (("short", 10.0),)]
    rows = _rows(out / RESULTS)
    for r in rows:
        if r[level] == "30.0":
            kept = {**old[(r["mode"], 30.0)], "point": r["point"]}  # timings too: not re-run
            assert {**r, "row_digest": ""} == {**kept, "row_digest": ""}
            assert r["row_digest"] == row_digest(kept)  # renumbered: its digest follows
    (backup,) = out.glob("results.before-*.csv")
    assert backup.read_bytes() == before
    monkeypatch.setattr(P, "_render", real)
    run_study(new, tmp_path / "fresh", workers=0, progress=False)
    drop = ("render_s", "total_s", "row_digest")  # the digest hashes the timings too
    strip = lambda rows: [{k: v for k, v in r.items() if k not in drop} for r in rows]  # noqa: E731
    assert strip(rows) == strip(_rows(tmp_path / "fresh" / RESULTS))


@pytest.mark.render
def test_a_point_added_to_a_rendered_group_gets_the_groups_noise_target(tmp_path):
    """With a noise target, a point added beside kept ones is rendered to the target of its
    whole render (the lowest noise of 30 and 3000 photons), so its row is a fresh run's: a
    render for it alone would stop at the noise of 30 photons, with fewer samples."""
    body = TINY.format(levels="[30.0, 3000.0]", ratio="0.2").replace('"coded", "short"', '"coded"')
    body = body.replace("spp = 4\n", "")
    (tmp_path / "a.toml").write_text(body)
    added = body + '[[points]]\nmode = "coded"\nlight_level = 30.0\nmethod = "none"\n'
    (tmp_path / "b.toml").write_text(added)
    out = tmp_path / "o"
    run_study(load_study(str(tmp_path / "a.toml")), out, workers=0, progress=False)
    before = _rows(out / RESULTS)
    with pytest.warns(PacamWarning, match="2 points kept .* 1 to run, 0 old rows set aside"):
        s = run_study(load_study(str(tmp_path / "b.toml")), out, workers=0, progress=False)
    assert (s.skipped, s.ran, s.failed) == (2, 1, 0)
    run_study(load_study(str(tmp_path / "b.toml")), tmp_path / "fresh", workers=0, progress=False)
    drop = ("render_s", "total_s", "row_digest")  # the digest hashes the timings too
    strip = lambda rows: [{k: v for k, v in r.items() if k not in drop} for r in rows]  # noqa: E731
    rows = _rows(out / RESULTS)
    assert rows[:2] == before and strip(rows) == strip(_rows(tmp_path / "fresh" / RESULTS))


def test_a_changed_design_file_reruns_its_points(tmp_path):
    """Issue 47 item 6: the point key hashes the design file a `design` axis names (the
    camera it makes): an edited R_mm is another camera, its rows are not kept."""
    from pacam_render.model.camera import prototype
    from pacam_render.model.design_file import write_design

    design = tmp_path / "s1.toml"
    write_design(design, prototype())
    path = tmp_path / "st.toml"
    path.write_text(
        '[study]\nname = "st"\n[render]\nwidth = 48\nheight = 36\nspp = 4\nmax_step_px = 4.0\n'
        f'[grid]\nmode = ["coded"]\ndesign = ["{design}"]\nlight_level = [300.0]\n'
    )
    first = run_study(load_study(str(path)), tmp_path / "out", workers=0, progress=False)
    assert first.ran == 1
    write_design(design, prototype().with_(R_mm=1.5), force=True)
    again = run_study(load_study(str(path)), tmp_path / "out", workers=0, progress=False)
    assert again.ran == 1  # not "1 already done"
