"""A read-only installation still compiles its kernels: numba is pointed at a temporary cache folder."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from cvstereo._numba_cache import can_write, fallback_cache_dir


def test_can_write(tmp_path):
    assert can_write(tmp_path / "new" / "folder")
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    assert not can_write(blocker / "sub")


def test_fallback_only_when_install_and_user_cache_are_read_only(tmp_path):
    ro = {Path("/site/cvstereo/__pycache__"), Path("/site/calibration_free/__pycache__"), Path("/home/u/.cache")}

    def writable(folder):
        return Path(folder) not in ro

    pkgs = ["/site/cvstereo", "/site/calibration_free"]
    assert fallback_cache_dir(pkgs, "/home/u/.cache", tmp_path, writable=writable) == tmp_path / "cvstereo-numba-cache"
    # A writable user cache: numba's own choice works, nothing to change.
    assert fallback_cache_dir(pkgs, "/home/u/other", tmp_path, writable=writable) is None
    # A writable install: nothing to change.
    assert fallback_cache_dir(["/site/other"], "/home/u/.cache", tmp_path, writable=writable) is None
    # Nothing writable at all: leave it to numba's own error.
    assert fallback_cache_dir(pkgs, "/home/u/.cache", tmp_path, writable=lambda d: False) is None


def test_user_choice_wins(tmp_path):
    """NUMBA_CACHE_DIR given by the user is kept as it is."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", "import cvstereo, numba; print(numba.config.CACHE_DIR)"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == str(tmp_path)


def test_user_cache_dir_is_numbas_own():
    from numba.misc.appdirs import AppDirs

    from cvstereo._numba_cache import numba_user_cache_dir

    assert numba_user_cache_dir() == Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)


def test_kernel_folders_are_the_folders_of_the_modules_with_cached_kernels():
    from cvstereo import _numba_cache

    package = Path(_numba_cache.__file__).parent
    with_kernels = {path.parent.relative_to(package).as_posix() for path in package.rglob("*.py")
                    if path.name != "_numba_cache.py" and "cache=True" in path.read_text()}
    assert with_kernels == set(_numba_cache.KERNEL_FOLDERS) and "matchers/frame" in with_kernels


# --- warm-up (issue 28 item 2): the cache filled in one process, used by the next; compilation said and untimed ---

_WARM = """
import json, sys
from numba.core.registry import CPUDispatcher
from cvstereo.cli import main
code = main(["warm-up", "--method", "stereobm"])
used = sorted({(name, obj.py_func.__qualname__, obj.py_func.__code__.co_firstlineno)
               for name, mod in list(sys.modules.items()) if name.startswith("cvstereo")
               for obj in list(vars(mod).values())
               if isinstance(obj, CPUDispatcher) and obj.overloads and obj.__module__ == name})
print(json.dumps({"code": code, "used": used}))
"""

_MATCH = """
import json
import numpy as np
import cvstereo as cvs
from cvstereo._compile_watch import compile_seconds, watch_compiles
watch_compiles()
rng = np.random.default_rng(5)  # another clip than the warm-up's
t = np.sort(rng.integers(0, 300_000, 3000))
x, y, p = rng.integers(10, 128, 3000), rng.integers(0, 128, 3000), rng.integers(0, 2, 3000)
rec = cvs.Recording(cvs.make_events(t, x, y, p), cvs.make_events(t, x - 10, y, p))
found = [len(cvs.match(rec, method="stereobm", param_set=s)) for s in ("adaptive", "thesis")]
print(json.dumps({"compile_s": compile_seconds(), "found": found}))
"""


def _python(code: str, cache: Path) -> tuple[dict, str]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1]), done.stderr


def test_warm_up_fills_a_cache_that_a_fresh_process_uses(tmp_path):
    """In an empty cache, ``cvstereo warm-up`` compiles (and says so once per group) and leaves numba's index file of
    every kernel it ran; a fresh process then matches another clip, under both parameter sets, compiling nothing."""
    from cvstereo.warmup import COMPILE_MESSAGE

    cache = tmp_path / "cache"
    warmed, err = _python(_WARM, cache)
    assert warmed["code"] == 0 and warmed["used"]
    # Once per group: the method's kernels, then the default rig check's (every match() runs it).
    assert err.count("compiling") == 2 and COMPILE_MESSAGE.format(group="stereobm") in err
    assert COMPILE_MESSAGE.format(group="rigcheck") in err
    tag = f"py{sys.version_info.major}{sys.version_info.minor}"
    indexes = {p.name for p in cache.rglob("*.nbi")}
    for module, qualname, line in warmed["used"]:
        assert f"{module.rsplit('.', 1)[1]}.{qualname}-{line}.{tag}.nbi" in indexes, (module, qualname)
    used, err = _python(_MATCH, cache)
    assert used["compile_s"] == 0.0 and "compiling" not in err
    assert min(used["found"]) > 0


def test_preparing_the_kernels_is_outside_the_reported_matching_time(monkeypatch):
    """``create_matcher`` prepares a built-in method's kernels (where they compile) before ``match()`` starts its
    clock: a preparation that takes 1 s leaves ``elapsed_s`` far below it."""
    import time

    import cvstereo as cvs
    from cvstereo import _compile_watch

    clip = _compile_watch.tiny_clip()
    cvs.match(clip, method="stereobm")  # its kernels in memory: the timed run below loads none
    calls = []

    def slow(matcher, group):
        calls.append((group, matcher.param_set))
        time.sleep(1.0)

    monkeypatch.setattr(_compile_watch, "prepare", slow)
    result = cvs.match(clip, method="stereobm")
    assert calls == [("stereobm", "adaptive")] and result.meta["elapsed_s"] < 1.0


_VARIANT = """
import json
from cvstereo.matchers._shared.sparse_frames import _mark_above
from cvstereo.matchers.registry import create_matcher
create_matcher("frame-area")  # the set's default, gaussian: it never calls _mark_above
default = len(_mark_above.overloads)
built = create_matcher("frame-area", "no-gaussian")
print(json.dumps({"default": default, "variant": len(_mark_above.overloads), "fed": built.input_events}))
"""


def test_the_matchers_own_variant_is_prepared_before_create_matcher_returns():
    """frame-area's no-gaussian variant runs a kernel (``sparse_frames._mark_above``) that the set's default does
    not: in a fresh process, building the default leaves it unloaded, building the variant has it compiled or
    loaded (a numba overload in memory) by the time create_matcher returns, the matcher itself unfed."""
    done = subprocess.run([sys.executable, "-c", _VARIANT], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got == {"default": 0, "variant": 1, "fed": 0}


def test_preparing_leaves_the_matcher_as_built(monkeypatch):
    """The prepared copy is fed, not the matcher: it comes back unfed and matches another clip as one built
    without preparing; OpenCV's matcher, which cannot be deep-copied, is prepared through a rebuilt copy."""
    from cvstereo import _compile_watch
    from cvstereo.matchers.registry import create_matcher, matcher_class
    from cvstereo.model.events import make_events

    rng = np.random.default_rng(5)  # another clip than the preparing one
    t = np.sort(rng.integers(0, 300_000, 8000))
    x, y, p = rng.integers(10, 128, 8000), rng.integers(0, 128, 8000), rng.integers(0, 2, 8000)
    left, right = make_events(t, x, y, p), make_events(t, x - 10, y, p)
    twin = _compile_watch._twin
    for method, variant in (("frame", "shared"), ("stereobm", None)):
        monkeypatch.setattr(_compile_watch, "_PREPARED", set())  # as in a fresh process
        runs = []
        monkeypatch.setattr(_compile_watch, "_twin", lambda m, runs=runs: runs.append(m) or twin(m))
        built = create_matcher(method, variant)
        assert runs == [built]
        assert (built.watermark, built.input_events, built.ended) == (None, 0, False)
        plain = matcher_class(method)(built.params, resolution=built.resolution)
        out = [np.concatenate([m.feed(left, right, until=300_000), m.flush()]) for m in (built, plain)]
        np.testing.assert_array_equal(out[0], out[1])
        assert out[0].size > 0


def test_one_preparation_per_compiled_path(monkeypatch):
    """A threshold's size is a kernel argument: a sweep over it prepares once. A scale of 0 switches the pace
    off, and another variant or thread count may run other kernels: each is a path of its own."""
    from cvstereo import _compile_watch
    from cvstereo.matchers.registry import create_matcher

    monkeypatch.setattr(_compile_watch, "_PREPARED", set())
    prepared = []
    twin = _compile_watch._twin
    monkeypatch.setattr(_compile_watch, "_twin", lambda m: prepared.append(m) or twin(m))
    made = [create_matcher("event-time", threshold_scale=s) for s in (2.0, 3.0, 4.0)]
    assert prepared == made[:1]
    paced_off = create_matcher("event-time", time_window_scale=0.0)
    shared = create_matcher("event-time", "shared")
    assert prepared == [made[0], paced_off, shared]
    threaded = create_matcher("event-time")
    threaded.threads = 2
    assert _compile_watch.compiled_path(threaded) != _compile_watch.compiled_path(made[0])
    assert _compile_watch.prepare(threaded, "event-time") and prepared[-1] is threaded
    more_threads = create_matcher("event-time")  # any count above one runs the same parallel kernels
    more_threads.threads = 3
    assert _compile_watch.compiled_path(more_threads) == _compile_watch.compiled_path(threaded)


def test_compilation_announced_once_per_group_and_timed_outermost(capsys):
    """Nested compilations (a kernel compiling the kernels it calls) are one; a group is announced once."""
    from types import SimpleNamespace

    from cvstereo._compile_watch import COMPILE_MESSAGE, _Watch

    def event(module):
        return SimpleNamespace(data={"dispatcher": SimpleNamespace(py_func=SimpleNamespace(__module__=module))})

    watch = _Watch()
    area = event("cvstereo.matchers.event_area.matcher")
    watch.on_start(area)
    watch.on_start(event("cvstereo.matchers._shared.sorted_runs"))  # nested: not announced, not timed twice
    watch.on_end(area)
    assert watch.total == 0.0  # still inside the outer compilation
    watch.on_end(area)
    first = watch.total
    watch.on_start(area)
    watch.on_end(area)
    watch.on_start(event("cvstereo.matchers._shared.sorted_runs"))
    watch.on_end(area)
    assert first > 0 and watch.total > first
    assert capsys.readouterr().err.splitlines() == [COMPILE_MESSAGE.format(group="event-area"),
                                                   COMPILE_MESSAGE.format(group="shared matcher")]


def test_live_prepares_the_kernels_before_it_opens_the_sensors(monkeypatch, tmp_path):
    from cvstereo import _compile_watch
    from cvstereo.cli import live
    from tests._hostile import run_cli

    order = []
    monkeypatch.setattr(_compile_watch, "prepare", lambda matcher, group: order.append(("prepare", group)))

    def no_rig(args):
        order.append(("open", None))
        raise OSError("no boards here")

    monkeypatch.setattr(live, "open_rig", no_rig)
    assert run_cli(["live", "--left", "/dev/null", "--right", "/dev/null", "-m", "event-area"]) == (1, "")
    assert order == [("prepare", "event-area"), ("open", None)]


def test_warm_up_unknown_method_is_one_line(capsys):
    from tests._hostile import run_cli

    assert run_cli(["warm-up", "--method", "nope"]) == (1, "")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("cvstereo warm-up: error: --method nope") and "event-area" in err[0]
