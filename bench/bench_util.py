"""Helpers shared by the Blender benchmarks (bench_placement.py, bench_spheres.py)."""
import resource


def cpu_seconds() -> float:
    """CPU seconds of this process (all threads, user + system): the load-independent cost on a
    machine shared with other jobs."""
    u = resource.getrusage(resource.RUSAGE_SELF)
    return u.ru_utime + u.ru_stime
