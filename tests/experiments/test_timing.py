"""The work by kind is CPU time: a block that sleeps counts nothing, one that computes counts
its CPU whatever else competes for the processor, a step counts the processes it ended but not
the work run ahead beside it (counted where it is taken), and a collection's kinds add up to
its worker's CPU time as the kernel counts it (/proc)."""

import os
import resource
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest

from drake_continuum.config import load_config
from drake_continuum.experiments import reproduce, schedule
from drake_continuum.experiments.collect import collect, warm_worker
from drake_continuum.experiments.timing import (
    Work,
    object_work,
    step_clock,
    step_table,
    work_table,
)
from drake_continuum.objects.dataset import generate_dataset
from drake_continuum.workers import local_pool

SHIPPED = load_config()
FIXED = replace(SHIPPED, planes=replace(SHIPPED.planes, bearing="world", centre="mark"))


def _thread_rusage() -> float:
    """This thread's CPU seconds as getrusage counts them (not time.thread_time's clock)."""
    usage = resource.getrusage(resource.RUSAGE_THREAD)
    return usage.ru_utime + usage.ru_stime


def _busy(seconds: float) -> int:
    """Compute for about `seconds` of wall time."""
    n, end = 0, time.perf_counter() + seconds
    while time.perf_counter() < end:
        n += sum(range(200))
    return n


def _count_to(n: int) -> int:
    """A fixed amount of computing: the same CPU time whatever the load."""
    return sum(k * k % 7 for k in range(n))


def test_a_block_that_sleeps_counts_no_cpu_and_one_that_computes_counts_its_cpu():
    work = Work()
    with work.timed("figures"):
        time.sleep(0.3)
    assert work["figures"] < 0.02
    before = _thread_rusage()
    with work.timed("training"):
        _busy(0.3)
    assert work["training"] > 0.05
    assert work["training"] == pytest.approx(_thread_rusage() - before, abs=0.02)


def test_a_block_waiting_for_the_processor_counts_the_same_cpu():
    """Another thread computing beside it (the GIL shares one core between them) doubles the
    block's wall time, not its CPU time."""
    def timed(competitor: bool) -> tuple:
        stop = threading.Event()
        other = threading.Thread(target=lambda: [_count_to(20_000) for _ in iter(stop.is_set,
                                                                                  True)])
        if competitor:
            other.start()
        work, t0 = Work(), time.perf_counter()
        with work.timed("wraps"):
            _count_to(3_000_000)
        wall = time.perf_counter() - t0
        stop.set()
        if competitor:
            other.join()
        return wall, work["wraps"]

    alone_wall, alone = timed(False)
    shared_wall, shared = timed(True)
    assert shared_wall > 1.5 * shared  # it waited for the processor ...
    assert 0.6 < shared / alone < 1.6  # ... and its CPU time did not grow with the wait


def test_a_step_counts_the_cpu_of_the_processes_it_ended():
    """step_clock adds the child processes ended: a child that computes for a while adds
    the CPU time it reports of itself, while this thread only waited."""
    code = ("import time\nend = time.perf_counter() + 0.4\nn = 0\n"
            "while time.perf_counter() < end:\n    n += 1\nprint(time.process_time())")
    c0, t0 = step_clock(), time.thread_time()
    child = float(subprocess.run([sys.executable, "-c", code], capture_output=True,
                                 text=True, check=True).stdout)
    assert time.thread_time() - t0 < 0.05
    assert step_clock() - c0 == pytest.approx(child, abs=0.05)
    assert child > 0.2


def test_work_run_ahead_counts_apart_from_the_step_running_meanwhile():
    """A thread run ahead (schedule.start) that computes: its CPU time is read while it runs
    and when it is taken, as the thread itself measures it, and the step's clock, which only
    waited, leaves it out."""
    seen, computed, go_on = {}, threading.Event(), threading.Event()

    def work():
        _busy(0.3)
        seen["computing"] = _thread_rusage()
        computed.set()
        go_on.wait()
        return "done"

    c0 = reproduce._clock()
    try:
        schedule.start("timed", work)
        computed.wait()
        live = schedule.ahead_cpu()
        go_on.set()
        result, ahead_s = schedule.take_timed("timed")
        step = reproduce._clock() - c0
    finally:
        go_on.set()
        schedule.end()
    assert result == "done" and seen["computing"] > 0.05
    assert live == pytest.approx(seen["computing"], abs=0.02)
    assert ahead_s == pytest.approx(seen["computing"], abs=0.02)
    assert step < 0.05
    assert schedule.take_timed("never started") == (None, None)


def test_object_work_sums_the_wraps_cpu_and_leaves_the_rest_to_the_scene():
    def wrap(cpu, ik, pose, prefilter, surfaces):
        return SimpleNamespace(time_s=9.0, extra={"timing": {
            "cpu_s": cpu, "ik": ik, "pose": pose, "prefilter": prefilter,
            "contact_surfaces": surfaces}})

    work = object_work(0.5, 3.0, [wrap(1.0, 0.25, 0.125, 0.0625, 0.25),
                                   wrap(0.75, 0.5, 0.0, 0.0, 0.125)])
    assert work == {"camera": 0.5, "scene": 3.0 - 0.5 - 1.75, "wraps": 1.75, "ik": 0.75,
                    "contact queries": 0.5625}


def test_the_tables_say_which_time_they_give():
    assert work_table({"wraps": 2.0, "ik": 1.0}).splitlines()[:4] == [
        "| work | CPU s |", "|---|---:|", "| wraps | 2.0 |", "| of which ik | 1.0 |"]
    assert step_table({"collect": {"time_s": 3.0}}).splitlines()[0] == "| step | wall s |"


def _process_cpu(pid: int) -> float:
    """A live process's CPU seconds (user + system) as the kernel counts them."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux's /proc")
def test_a_collections_kinds_add_up_to_its_workers_cpu(tmp_path):
    """On a warmed worker, the objects' kinds (camera, scene, wraps) are the CPU time the
    kernel counted for the worker over the collection (its task's transport aside)."""
    generate_dataset(tmp_path / "objects", counts={"apple": 1, "cup": 1}, workers=1,
                     progress=False)
    with local_pool(1) as pool:
        pool.submit(warm_worker).result()
        (pid,) = pool._processes
        worker0 = _process_cpu(pid)
        report = collect(tmp_path / "objects", tmp_path / "wraps", FIXED, planes=[0],
                         scheduler=pool, progress=False)
        worker = _process_cpu(pid) - worker0
    work = report.work_s
    objects = work["camera"] + work["scene"] + work["wraps"]
    assert report.done and worker > 0.2
    assert objects == pytest.approx(worker, rel=0.1, abs=0.1)
    assert objects == pytest.approx(sum(report.object_cpu_s.values()), rel=1e-9)
    assert 0 < work["ik"] + work["contact queries"] < work["wraps"]
