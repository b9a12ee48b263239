"""``pacam study``: spec checking, scoring, scene edits for sweeps, the Dask engine (a real
LocalCluster against the serial run), resuming, failures and worker deaths."""

import csv
import os
import sys

import numpy as np
import pytest

from pacam_render.errors import ParameterError
from pacam_render.model.camera import prototype
from pacam_render.restore.object_score import best_shift_se, score
from pacam_render.scenes import load_scene
from pacam_render.scenes.edit import at_depth, scaled_motion, scene_speed_px_per_ms, with_speed
from pacam_render.scenes.motion import Motion
from pacam_render.study import builtin_studies, load_study, run_study
from pacam_render.study import engine as E
from pacam_render.study.spec import parse_study

TINY = """
[study]
name = "tiny"
report = "crossover"
[render]
width = 48
height = 36
spp = 4
noise_ratio = 0.2
max_step_px = 4.0
[grid]
mode = ["coded", "short"]
light_level = [30.0, 3000.0]
"""


def _tiny(tmp_path, text=TINY):
    path = tmp_path / "tiny.toml"
    path.write_text(text)
    return load_study(str(path))


def _rows(out):
    with open(out / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


# --- the spec ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "doc, words",
    [
        ({"gird": {}}, "unknown key 'gird'"),
        ({"grid": {"speed": [1.0]}}, "[grid]: unknown key 'speed'"),
        ({"render": {"wdith": 3}}, "[render]: unknown key 'wdith'"),
        ({"grid": {"mode": []}}, "[grid] mode must be a non-empty list"),
        ({"grid": {"light_level": [-1.0]}}, "light_level must be in [1e-06, 1e+09]"),
        ({"grid": {"scene": ["nope"]}}, "unknown scene 'nope'"),
        ({"grid": {"mode": ["blurry"]}}, "unknown mode 'blurry'"),
        ({"grid": {"mode": ["reference"]}}, "unknown mode 'reference'"),
        ({"grid": {"method": ["magic"]}}, "unknown method 'magic'"),
        ({"grid": {"design": ["cover:2"]}}, "design must be 'prototype' or 'cover=S'"),
        ({"grid": {"design": ["F=4"]}}, "design 'F=4' needs cover=S"),
        ({"grid": {"design": ["cover=1e6"]}}, "design 'cover=1e6'"),
        ({"grid": {"sensor": ["potato"]}}, "potato"),
        ({"grid": {"seed": [-1]}}, "seed must be an integer in [0, 2^31)"),
        ({"render": {"spp": 0}}, "[render] spp must be an integer >= 1"),
        ({"study": {"report": "pie"}}, "[study] report must be one of"),
        ({"points": [{"mode": "coded", "colour": 1}]}, "[[points]] #1: unknown key 'colour'"),
    ],
)
def test_a_bad_spec_is_refused_naming_its_key(doc, words):
    with pytest.raises(ParameterError) as err:
        parse_study(doc)
    assert words in str(err.value)


def test_bad_files_and_names(tmp_path):
    (tmp_path / "bad.toml").write_text("[grid\nmode = 1")
    with pytest.raises(ParameterError, match="not valid TOML"):
        load_study(str(tmp_path / "bad.toml"))
    with pytest.raises(ParameterError, match="unknown study 'nosuch'; built-in: crossover"):
        load_study("nosuch")


def test_grid_expansion_groups_and_key(tmp_path):
    spec = parse_study(
        {"grid": {"mode": ["coded", "normal"], "method": ["hl", "wiener"], "light_level": [1, 2]}}
    )
    assert len(spec.points) == 2 * 2 * 2
    assert len(spec.groups()) == 2  # one render per mode
    assert [p.index for p in spec.points] == list(range(8))
    dup = parse_study({"grid": {"mode": ["coded"]}, "points": [{"mode": "coded"}]})
    assert len(dup.points) == 1  # a point given twice is one point
    again = parse_study(
        {"grid": {"mode": ["coded", "normal"], "method": ["hl", "wiener"], "light_level": [1, 2]}}
    )
    assert spec.key() == again.key()
    assert parse_study({"grid": {"light_level": [1, 3]}}).key() != spec.key()


@pytest.mark.parametrize("name", ["crossover", "speed"])
def test_builtin_studies_parse_full_and_quick(name):
    assert name in builtin_studies()
    full, quick = load_study(name), load_study(name, quick=True)
    assert len(quick.points) < len(full.points)
    assert quick.render["spp"] * np.prod(
        quick.render["crop"][2:]
        if quick.render["crop"]
        else (quick.render["width"], quick.render["height"])
    ) < full.render["spp"] * np.prod(full.render["crop"][2:])


# --- scoring -------------------------------------------------------------------------------------
def test_best_shift_finds_a_known_shift_and_matches_brute_force():
    rng = np.random.default_rng(1)
    truth = rng.random((20, 40, 3))
    est = np.roll(truth, 3, axis=1) + 0.01 * rng.normal(size=truth.shape)
    mask = np.zeros((20, 40), bool)
    mask[5:15, 10:30] = True
    se, d = best_shift_se(est, truth, mask, 5)
    assert d == 3
    r, c = np.nonzero(mask)
    assert se == pytest.approx(np.sum((est[r, c + 3] - truth[r, c]) ** 2))


def test_score_per_object_against_brute_force():
    rng = np.random.default_rng(2)
    truth = rng.random((16, 40, 3))
    ids = np.ones((16, 40))
    ids[4:12, 12:28] = 2  # the moving object
    est = truth + 0.1  # the still rest is off by 0.1 ...
    r, c = np.nonzero(ids == 2)
    est[r, c + 2] = truth[r, c]  # ... and the object is exact, moved right by 2 px
    s = score(est, {"sharp": truth, "object_id": ids}, {"1": "wall", "2": "ball"}, {"ball"}, 4)
    assert s["psnr_moving_db"] == np.inf  # exact at its best shift
    still = (ids == 1)[:, 4:36]
    mse = np.mean((est[:, 4:36] - truth[:, 4:36])[still] ** 2)
    assert s["psnr_static_db"] == pytest.approx(-10 * np.log10(mse), abs=1e-9)
    assert '"ball": [Infinity, 2]' in s["psnr_by_object"]
    # the interior leaves out a band at the outline: spoil only that band, and only it is lost
    est[r, c + 2] = np.where((c < 15)[:, None], truth[r, c] + 0.5, truth[r, c])
    near = score(est, {"sharp": truth, "object_id": ids}, {"1": "w", "2": "ball"}, {"ball"}, 4, 3)
    assert near["psnr_moving_interior_db"] == np.inf and near["psnr_moving_db"] < 20


# --- scene edits for sweeps ----------------------------------------------------------------------
def test_with_speed_and_at_depth():
    cam = prototype()
    train = load_scene("train")
    assert scene_speed_px_per_ms(train, cam) == pytest.approx(1.4, rel=1e-6)
    fast = with_speed(train, 2.1, cam)
    assert scene_speed_px_per_ms(fast, cam) == pytest.approx(2.1, rel=1e-6)
    assert scene_speed_px_per_ms(train, cam) == pytest.approx(1.4, rel=1e-6)  # unchanged
    ball = load_scene("soccer")
    moved = at_depth(ball, 700.0, cam)
    assert moved.depths_mm["ball"] == 700.0 and ball.depths_mm["ball"] != 700.0
    assert scene_speed_px_per_ms(moved, cam) == pytest.approx(
        scene_speed_px_per_ms(ball, cam), rel=1e-3
    )
    assert moved.scene_dict["ball"]["to_world"][2, 3] == pytest.approx(
        700.0 - ball.depths_mm["ball"]
    )


def test_scaled_motion_is_the_motion_run_faster():
    rot = np.eye(4)
    rot[:2, :2] = [[0, -1], [1, 0]]
    m = Motion((1.0, 0.0, 0.0), ((-10.0, np.eye(4)), (10.0, rot)), (0.0, 0.0, 5.0))
    k = scaled_motion(m, 2.0)
    np.testing.assert_allclose(k.matrix_at(2.5), m.matrix_at(5.0))


# --- the engine ----------------------------------------------------------------------------------
@pytest.mark.render
def test_local_cluster_of_two_equals_the_serial_run(tmp_path):
    spec = _tiny(tmp_path)
    serial = run_study(spec, tmp_path / "serial", workers=0, progress=False)
    dask2 = run_study(spec, tmp_path / "dask", workers=2, progress=False)
    assert serial.ran == dask2.ran == 4 and serial.failed == dask2.failed == 0
    assert serial.dashboard is None and dask2.dashboard.startswith("http://")
    a, b = _rows(tmp_path / "serial"), _rows(tmp_path / "dask")
    drop = ("render_s", "total_s", "row_digest")  # the digest hashes the timings too
    assert [{k: v for k, v in r.items() if k not in drop} for r in a] == [
        {k: v for k, v in r.items() if k not in drop} for r in b
    ]
    assert (tmp_path / "dask" / "report.md").read_text().count("coded") > 0


def _overlaps(tasks: list) -> list[tuple]:
    """(worker, task, task) for each two pacam tasks whose compute intervals overlap on one
    worker, from a Dask task stream's records."""
    spans: dict = {}
    for t in tasks:
        if not str(t.get("key", "")).startswith("pacam-"):
            continue
        for ss in t.get("startstops", ()):
            if ss.get("action") == "compute":
                spans.setdefault(t.get("worker"), []).append((ss["start"], ss["stop"], t["key"]))
    out = []
    for worker, iv in spans.items():
        iv.sort()
        out += [(worker, a[2], b[2]) for a, b in zip(iv, iv[1:]) if b[0] < a[1]]
    return out


def test_overlaps_names_tasks_that_ran_at_once():
    def c(key, a, b, w="w1"):
        return {"key": key, "worker": w,
                "startstops": ({"action": "compute", "start": a, "stop": b},)}  # fmt: skip

    tasks = [c("pacam-a", 0, 2), c("pacam-b", 1, 3), c("pacam-c", 3, 4), c("pacam-d", 1, 2, "w2"),
             c("other", 0, 9)]  # fmt: skip
    assert _overlaps(tasks) == [("w1", "pacam-a", "pacam-b")]


@pytest.mark.render
def test_a_study_runs_on_a_client_of_your_own_and_leaves_it_open(tmp_path):
    """``run_study(client=...)``: every point is a task on that cluster (its task stream shows
    them), the results are the serial run's, and the client is still open afterwards."""
    import dask
    from distributed import Client, LocalCluster, get_task_stream

    spec = _tiny(tmp_path)
    run_study(spec, tmp_path / "serial", workers=0, progress=False)
    spawn = {"distributed.worker.multiprocessing-method": "spawn"}
    # two threads on the one worker (LocalCluster's default on 2 cores): pacam's tasks run one
    # at a time there all the same; two at once in one process is the likely cause of the
    # "ran 4, failed 2" this test gave on a loaded machine
    cluster_kw = dict(n_workers=1, threads_per_worker=2, dashboard_address=None)
    with dask.config.set(spawn), LocalCluster(**cluster_kw) as cluster:
        with Client(cluster) as client, get_task_stream(client) as stream:
            summary = run_study(spec, tmp_path / "mine", client=client, progress=False)
            assert client.status == "running"
        assert summary.dashboard == client.dashboard_link  # printed with the progress
    failed = [(r["point"], r["status"]) for r in _rows(tmp_path / "mine") if r["status"] != "ok"]
    # a failed point says why, and which pacam tasks overlapped on one worker (Dask's compute
    # intervals include the wait for the engine's lock, so overlaps alone are not a fault): the
    # next failure under load names what ran beside it
    assert summary.ran == 4 and summary.failed == 0, (failed, _overlaps(stream.data))
    assert sum(t["key"].startswith("pacam-") for t in stream.data) == 4  # 2 pilots, 2 renders
    drop = ("render_s", "total_s", "row_digest")  # the digest hashes the timings too
    a, b = _rows(tmp_path / "serial"), _rows(tmp_path / "mine")
    assert [{k: r[k] for k in r if k not in drop} for r in a] == [
        {k: r[k] for k in r if k not in drop} for r in b
    ]


@pytest.mark.render
def test_an_interrupted_study_resumes_to_the_same_results(tmp_path, monkeypatch):
    import pacam_render.study as S

    spec = _tiny(tmp_path)
    run_study(spec, tmp_path / "whole", workers=0, progress=False)
    real = S.run_tasks

    def one_then_ctrl_c(fn, tasks, on_done, *engine, **kw):
        if fn is not S.run_task:  # the pilot passes run whole
            return real(fn, tasks, on_done, *engine, **kw)
        on_done(tasks[0], fn(tasks[0]))
        raise KeyboardInterrupt

    monkeypatch.setattr(S, "run_tasks", one_then_ctrl_c)
    with pytest.raises(KeyboardInterrupt):
        run_study(spec, tmp_path / "cut", workers=0, progress=False)
    assert len(_rows(tmp_path / "cut")) == 2  # the finished render's points, a whole CSV
    monkeypatch.setattr(S, "run_tasks", real)
    again = run_study(spec, tmp_path / "cut", workers=0, progress=False)
    assert (again.skipped, again.ran) == (2, 2)
    drop = ("render_s", "total_s", "row_digest")  # the digest hashes the timings too
    strip = lambda rows: [{k: v for k, v in r.items() if k not in drop} for r in rows]  # noqa: E731
    assert strip(_rows(tmp_path / "cut")) == strip(_rows(tmp_path / "whole"))


@pytest.mark.render
def test_a_failing_point_is_recorded_and_the_rest_finish(tmp_path):
    text = TINY.replace('mode = ["coded", "short"]', 'mode = ["coded"]')
    (tmp_path / "broken.xml").write_text("<scene version='3.0.0'><shape type='nope'/></scene>")
    text += f'\n[[points]]\nmode = "normal"\nscene = "{tmp_path / "broken.xml"}"\n'
    spec = _tiny(tmp_path, text)
    s = run_study(spec, tmp_path / "out", workers=0, progress=False)
    rows = _rows(tmp_path / "out")
    assert s.failed == 1 and len(rows) == 3
    bad = [r for r in rows if r["status"] != "ok"]
    assert bad[0]["mode"] == "normal" and "does not load" in bad[0]["status"]


def test_another_studys_folder_is_refused_without_force(tmp_path):
    """Of a folder written before rows had point keys (see test_study_resume.py for the rest)."""
    out = tmp_path / "o"
    from pacam_render.study.results import Results

    Results(out if out.mkdir() is None else out, parse_study({"grid": {"light_level": [1]}}))
    (out / "results.csv").write_text("point,status\n0,ok\n")  # no point_key column
    with pytest.raises(ParameterError, match="holds results of another study"):
        Results(out, parse_study({"grid": {"light_level": [2]}}))
    Results(out, parse_study({"grid": {"light_level": [2]}}), force=True)


def test_unreachable_scheduler_is_a_clear_error_within_the_timeout(monkeypatch):
    import time

    monkeypatch.setattr(E, "CONNECT_TIMEOUT_S", 2.0)
    t0 = time.perf_counter()
    with pytest.raises(ParameterError, match="`scheduler` tcp://127.0.0.1:9: no Dask scheduler"):
        E.run_tasks(abs, [1], lambda t, r: None, scheduler="tcp://127.0.0.1:9")
    assert time.perf_counter() - t0 < 15


@pytest.mark.parametrize("address", ["foo", "tcp://", "nonsense:::"])
def test_a_malformed_scheduler_address_is_refused_at_once(address):
    with pytest.raises(ParameterError, match="`scheduler` must be a Dask scheduler's address"):
        E.check_scheduler(address)


def _die_or_square(x):
    if x < 0:
        os._exit(3)  # the worker process dies mid-task
    return x * x


def test_a_task_whose_worker_dies_is_retried_once_then_failed(monkeypatch):
    import cloudpickle
    from distributed import KilledWorker

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # workers cannot import tests
    got = {}
    E.run_tasks(_die_or_square, [2, -1, 3], lambda t, r: got.__setitem__(t, r), workers=2)
    assert got[2] == 4 and got[3] == 9
    assert isinstance(got[-1], KilledWorker)


def test_workers_flag_is_checked_and_bounded_before_any_process_starts(monkeypatch):
    from pacam_render.limits import PacamWarning

    with pytest.raises(ParameterError, match="`workers` must be an integer >= 0"):
        E.check_workers(-1)
    assert E.check_workers(None) == os.cpu_count()
    for asked, tasks in ((6, 2), (1000, 50), (100000, None)):  # issue 26: 1000 ran out of memory
        with pytest.warns(PacamWarning, match=f"`workers` {asked} is more than this run can use"):
            got = E.check_workers(asked, tasks)
        assert got == min(tasks or asked, os.cpu_count())
    monkeypatch.setattr(E, "available_bytes", lambda: 3 * E.WORKER_BYTES)
    with pytest.warns(PacamWarning, match="3 memory"):
        assert E.check_workers(64, 64) == min(3, os.cpu_count())


def test_cli_refuses_a_bad_spec_before_any_work(tmp_path, capsys):
    from pacam_render.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text('[grid]\nmode = ["coded"]\nlight = [1.0]\n')
    assert main(["study", str(bad), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "[grid]: unknown key 'light'" in err and not (tmp_path / "o").exists()


@pytest.mark.render
def test_cli_runs_a_study_and_resumes(tmp_path, capsys):
    from pacam_render.cli import main

    path = tmp_path / "tiny.toml"
    path.write_text(TINY)
    argv = ["study", str(path), "--out", str(tmp_path / "o"), "--workers", "0", "--quiet"]
    assert main(argv) == 0
    assert "4 points run, 0 already done, 0 failed" in capsys.readouterr().out
    assert main(argv) == 0
    assert "0 points run, 4 already done" in capsys.readouterr().out
    assert {"results.csv", "report.md", "crossover.png", "crossover_map.png", "study.json"} <= {
        p.name for p in (tmp_path / "o").iterdir()
    }


def test_a_worker_runs_one_pacam_task_at_a_time_whatever_its_threads():
    """The lock around each task: two tasks submitted to one process's threads never overlap."""
    import threading
    import time

    from pacam_render.study.engine import _call

    inside, most, guard = [0], [0], threading.Lock()

    def task(_):
        with guard:
            inside[0] += 1
            most[0] = max(most[0], inside[0])
        time.sleep(0.05)
        with guard:
            inside[0] -= 1

    threads = [threading.Thread(target=_call, args=(task, i, None)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert most[0] == 1


def test_an_spp_without_a_noise_ratio_is_the_samples(tmp_path):
    """Issue 46: a [render] spp was silently overridden by the default noise target."""
    own = _tiny(tmp_path, TINY.replace("spp = 4\nnoise_ratio = 0.2\n", "spp = 256\n"))
    assert own.render["spp"] == 256 and own.render["noise_ratio"] is None
    both = _tiny(tmp_path, TINY)
    assert both.render["noise_ratio"] == 0.2  # given with it, the spp is the pilot's
    default = _tiny(tmp_path, TINY.replace("spp = 4\nnoise_ratio = 0.2\n", ""))
    assert default.render["noise_ratio"] == 0.2


def test_a_family_range_is_a_scene_axis_of_its_seeds():
    """Issue 57 item 4: ``family:NAME:FIRST-LAST`` in the scene axis lists its seeds (one
    render group per scene); a bad range or family is refused naming it."""
    spec = parse_study({"grid": {"scene": ["family:occluders:3-5", "train"], "mode": ["coded"]}})
    assert [p.scene for p in spec.points] == [
        "family:occluders:3", "family:occluders:4", "family:occluders:5", "train"
    ]  # fmt: skip
    assert len(spec.groups()) == 4
    with pytest.raises(ParameterError, match="FIRST <= LAST"):
        parse_study({"grid": {"scene": ["family:occluders:5-3"]}})
    with pytest.raises(ParameterError, match="occludrs"):
        parse_study({"grid": {"scene": ["family:occludrs:1-2"]}})


@pytest.mark.render
def test_a_study_runs_over_family_seeds(tmp_path):
    """Two seeds of the occluders family, each its own scene, scored on their moving
    objects (a window of the family's where both seeds have some)."""
    text = TINY.replace(
        "width = 48\nheight = 36", "width = 1280\nheight = 960\ncrop = [640, 430, 96, 72]"
    )
    text = text.replace(
        'mode = ["coded", "short"]', 'mode = ["coded"]\nscene = ["family:occluders:0-1"]'
    )
    text = text.replace("light_level = [30.0, 3000.0]", "light_level = [300.0]")
    run_study(_tiny(tmp_path, text), tmp_path / "out", workers=0, progress=False)
    rows = _rows(tmp_path / "out")
    assert [r["scene"] for r in rows] == ["family:occluders:0", "family:occluders:1"]
    assert all(r["status"] == "ok" and float(r["psnr_moving_db"]) > 0 for r in rows)


@pytest.mark.render
def test_a_crossover_study_without_a_scored_moving_object_reports_without_curves(tmp_path):
    """At 48x36 the family's objects are a few pixels: no moving object is scored, and the
    report says so instead of failing to draw empty small multiples."""
    text = TINY.replace(
        'mode = ["coded", "short"]', 'mode = ["coded"]\nscene = ["family:occluders:0"]'
    )
    text = text.replace("light_level = [30.0, 3000.0]", "light_level = [300.0]")
    run_study(_tiny(tmp_path, text), tmp_path / "out", workers=0, progress=False)
    assert _rows(tmp_path / "out")[0]["psnr_moving_db"] == "nan"
    assert "crossover curves are not drawn" in (tmp_path / "out" / "report.md").read_text()
