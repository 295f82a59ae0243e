"""Farm bakes on an existing farm engine (docs/farm.md): Slurm job arrays submitted with ``sbatch``,
and a Flamenco job type (``flamenco/schnee_probes_bake.js``). No scheduling here: the farm engine
runs the shards (``bake.py -- --shard K/N``), requeues what fails, and runs the merge
(``--merge-shards N``) after every shard succeeded. Shards resume from their journals, so a
requeued task re-renders only what it had not finished.

Plain Python (no Blender): ``bake.py --farm slurm`` calls :func:`submit_slurm`.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
from typing import Callable, List, Optional, Sequence

from .file_names import sibling


class FarmError(RuntimeError):
    """Submission failed; the message says what to do."""


FLAMENCO_JOB_TYPE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "flamenco", "schnee_probes_bake.js")


def _script(lines: Sequence[str]) -> str:
    return "\n".join(["#!/bin/sh"] + list(lines)) + "\n"


def slurm_scripts(blender: str, blend: str, bake_py: str, bake_args: Sequence[str], shards: int, folder: str,
                  sbatch_options: Sequence[str] = ()) -> dict:
    """The two batch scripts of a Slurm bake: ``shards.sbatch`` (a job array, one task per shard,
    requeueable; each task bakes share $SLURM_ARRAY_TASK_ID of ``shards``) and ``merge.sbatch``.
    ``bake_args`` are bake.py's options (settings, --output) shared by every job."""
    if shards < 1:
        raise FarmError("--shards must be at least 1")
    base = [blender, "-b", blend, "-P", bake_py, "--", *bake_args]
    # Cycles uses the CPUs Slurm gave the task (--cpus-per-task), all of the node's without it.
    cmd = " ".join(shlex.quote(a) for a in base[:3]) + ' -t "${SLURM_CPUS_PER_TASK:-0}" ' + " ".join(
        shlex.quote(a) for a in base[3:])
    common = [f"#SBATCH {o}" for o in sbatch_options]
    shard = _script([
        "#SBATCH --job-name=schnee-shard",
        f"#SBATCH --array=0-{shards - 1}",
        # Requeued after a node failure or preemption (or `scontrol requeue`): the task resumes
        # from its shard journal, so nothing finished is rendered twice.
        "#SBATCH --requeue",
        "#SBATCH --open-mode=append",
        f"#SBATCH --output={os.path.join(folder, 'shard-%A_%a.log')}",
        *common,
        "exec " + cmd + f' --shard "$SLURM_ARRAY_TASK_ID/{shards}"',
    ])
    merge = _script([
        "#SBATCH --job-name=schnee-merge",
        "#SBATCH --requeue",
        "#SBATCH --open-mode=append",
        f"#SBATCH --output={os.path.join(folder, 'merge-%j.log')}",
        *common,
        "exec " + cmd + f" --merge-shards {shards}",
    ])
    return {"shards.sbatch": shard, "merge.sbatch": merge}


def _sbatch(sbatch: str, script: str, extra: Sequence[str] = ()) -> str:
    try:
        proc = subprocess.run([sbatch, "--parsable", *extra, script], capture_output=True, text=True, timeout=120)
    except FileNotFoundError:  # removed since find_sbatch() found it
        raise FarmError(f"'{sbatch}' not found: {_SBATCH_HINT}") from None
    except subprocess.TimeoutExpired:
        raise FarmError(f"{sbatch} did not answer within 120 s: is slurmctld reachable?") from None
    if proc.returncode != 0:
        raise FarmError(f"{sbatch} {os.path.basename(script)} failed (exit {proc.returncode}): "
                        f"{proc.stderr.strip() or proc.stdout.strip()}")
    m = re.match(r"\s*(\d+)", proc.stdout)
    if not m:
        raise FarmError(f"{sbatch} printed no job id: {proc.stdout.strip()!r}")
    return m.group(1)


_SBATCH_HINT = ("run the submission on a Slurm login node, add the folder that holds sbatch to PATH, or give "
                "its path with --sbatch PATH (e.g. --sbatch /usr/bin/sbatch)")


def find_sbatch(sbatch: str = "sbatch") -> str:
    """The absolute path of the ``sbatch`` program to run: ``sbatch`` as given (a path) or looked up
    on PATH (a bare name). :class:`FarmError` naming the option when there is none."""
    found = shutil.which(sbatch)
    if found:
        return os.path.abspath(found)
    if os.sep in sbatch:
        raise FarmError(f"--sbatch {sbatch}: no executable file there; give the path of Slurm's sbatch "
                        "program (e.g. --sbatch /usr/bin/sbatch)")
    raise FarmError(f"'{sbatch}' not found on PATH ({os.environ.get('PATH', '')}): {_SBATCH_HINT}")


def farm_folder(output: str) -> str:
    """Where the batch scripts and job logs of a farm bake of ``output`` go: ``<output>.farm``."""
    return sibling(output, ".farm")


def submit_slurm(blender: str, blend: str, bake_py: str, bake_args: Sequence[str], shards: int, output: str,
                 sbatch_options: Sequence[str] = (), sbatch: str = "sbatch", stages: int = 1) -> List[str]:
    """Write the batch scripts into ``<output>.farm/`` and submit: one shard array per stage of the
    placement (``stages``: 1 for a one-pass placement, the refinement's bound for Adaptive), each
    with ``--dependency=afterok:<previous array>``, then the merge after the last (each runs only
    once every task before it succeeded, requeues included). Every array runs the same command: a
    shard takes the finished stages from the journals and bakes its share of the first unfinished
    one. ``sbatch``: the program (a path, or a name looked up on PATH), checked before anything is
    written. Returns [array job ids..., merge job id]."""
    if not os.path.isabs(blend):
        raise FarmError(f"the .blend path must be absolute for farm nodes: {blend}")
    sbatch = find_sbatch(sbatch)
    folder = farm_folder(output)
    os.makedirs(folder, exist_ok=True)
    paths = {}
    for name, text in slurm_scripts(blender, blend, bake_py, bake_args, shards, folder, sbatch_options).items():
        path = os.path.join(folder, name)
        tmp = f"{path}.{os.getpid()}.partial"
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.chmod(tmp, 0o755)
        os.replace(tmp, path)
        paths[name] = path
    if stages < 1:
        raise FarmError("stages must be at least 1")
    arrays: List[str] = []
    for _ in range(stages):
        dep = [f"--dependency=afterok:{arrays[-1]}", "--kill-on-invalid-dep=yes"] if arrays else []
        arrays.append(_sbatch(sbatch, paths["shards.sbatch"], dep))
    merge = _sbatch(sbatch, paths["merge.sbatch"], [f"--dependency=afterok:{arrays[-1]}", "--kill-on-invalid-dep=yes"])
    return arrays + [merge]


def job_journals(output: str, shards: int, only_volume: Optional[str] = None) -> List[str]:
    """The journals the jobs of a farm bake of ``output`` open: the ``shards`` shard journals and the
    merge's local journal, named after the volume's own file for a rebake (``--only-volume``)."""
    from .region import volume_file
    target = output if only_volume is None else volume_file(output, only_volume)
    # bake_points.shard_journal_path and local_journal_path's names (normative, docs/farm.md "Shards");
    # spelled here because bake_points needs Blender (bake_outputs imports bpy) and this module does not.
    return [sibling(target, f".shard-{k}-of-{shards}.journal") for k in range(shards)] + [sibling(target, ".journal")]


def prepare_journals(paths: Sequence[str], manifest: Callable[[], dict], restart: bool = False) -> List[str]:
    """Before submitting: the existing journals among ``paths`` (:func:`job_journals`) must belong to
    this bake, as every job checks (shards and merges refuse a journal of another bake; docs/farm.md),
    so a journal left by an earlier farm bake of an edited scene fails here, once, instead of in
    every job. ``manifest``: the bake's journal manifest, computed only when a journal exists.
    Journals of this bake are kept (resubmitted jobs resume from them). ``restart`` (``--restart``,
    which the jobs themselves never get: a requeued task must resume) removes them all instead, once
    no running job holds the lock of any of them (else nothing is removed). Returns the removed paths."""
    from . import journal
    from .output_lock import OutputBusy, OutputLock
    found = [p for p in paths if os.path.lexists(p)]
    if restart:  # every lock first: a refusal removes nothing
        locks = [OutputLock(p) for p in found]
        try:
            for path, lock in zip(found, locks):
                try:
                    lock.acquire()
                except OutputBusy as busy:
                    raise FarmError(f"a job is writing {path} ({busy.holder_text()}); wait for it or cancel it "
                                    "(scancel), then submit again") from None
            for path in found:
                os.unlink(path)
        finally:
            for lock in locks:
                lock.release()
        return found
    if found:
        want = manifest()
        for path in found:
            try:
                journal.read(path, expect_manifest=want)
            except journal.JournalError as exc:
                names = ", ".join(os.path.basename(p) for p in found)
                raise FarmError(f"{exc}, or submit with --restart (removes {names}); nothing was submitted: "
                                "every job would refuse it") from None
    return []


def forwarded_args(argv: Sequence[str], drop_with_value=("--farm", "--shards", "--sbatch-option", "--sbatch",
                                                         "--shard", "--merge-shards"),
                   drop_flags=("--restart",), output: Optional[str] = None) -> List[str]:
    """bake.py's own options minus the farm ones, with ``--output`` made absolute (farm nodes may
    start in another folder)."""
    out, skip = [], False
    for a in argv:
        if skip:
            skip = False
            continue
        name = a.split("=", 1)[0]
        if name in drop_with_value:
            skip = "=" not in a
            continue
        if name in drop_flags or name == "--output":
            if name == "--output":
                skip = "=" not in a
            continue
        out.append(a)
    if output is not None:
        out += ["--output", output]
    return out
