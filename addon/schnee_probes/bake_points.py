"""The bake's point store: the journal every rendered point is appended to, the shard filter and
the merge of the shards' journals (journal.py holds the file format; docs/farm.md the workflow).

Part of the bake (bake_core.ProbeBake drives it, for volume bakes)::

    store = PointStore(output_path, shard=(k, n) or None, merge_shards=n or None, restart=False,
                       log=print, messages=[])
    store.lock()                          # before anything else: one bake per journal (output_lock.py)
    store.open(manifest, coeff_count)     # the points this bake and the shards already hold
    hit = store.lookup(key)               # (coeffs, noise) of a point baked before, or None
    store.others(j)                       # point j of a stage is another shard's
    store.append(key, coeffs, noise)      # durably, after each render
    store.close()
    store.unlock()                        # once the files are written or the bake gave up

A bake that finds a matching journal takes its points from it instead of rendering them again.
shard = (k, n): render only the k-th of every n points of each stage (the rest come from the
other shards' journals) and write no .shprobe; merge_shards = n: take every point from the n shard
journals (and the local one) and write the files.
"""
from __future__ import annotations

import os
from typing import Optional, Tuple

from . import journal, scene_export
from .bake_outputs import abspath, check_replaceable
from .file_names import sibling
from .output_lock import OutputBusy, OutputLock
from .settings import BakeError

# The journal beside the output (docs/farm.md): <output>.journal, a shard's <output>.shard-K-of-N.journal
# (names over 255 bytes shortened by file_names.sibling, the same in every run).
JOURNAL_SUFFIX = ".journal"


def local_journal_path(output: str) -> str:
    """The local journal of a bake writing ``output`` (an absolute path)."""
    return sibling(output, JOURNAL_SUFFIX)


def journal_path_for(output_path: str) -> str:
    """The local journal of a bake writing ``output_path`` (may start with ``//``)."""
    return local_journal_path(abspath(output_path))


def shard_journal_path(output: str, k: int, n: int) -> str:
    return sibling(output, f".shard-{k}-of-{n}{JOURNAL_SUFFIX}")


def check_shards(shard, merge_shards) -> Optional[Tuple[int, int]]:
    """``shard`` as (k, n) ints, or None; ValueError for a bad pair or a shard that also merges."""
    if shard is not None and not (len(shard) == 2 and 0 <= shard[0] < shard[1]):
        raise ValueError(f"shard must be (k, n) with 0 <= k < n, not {shard!r}")
    if shard is not None and merge_shards is not None:
        raise ValueError("a bake is either one shard or the merge of the shards")
    if merge_shards is not None and merge_shards < 1:
        raise ValueError("merge_shards must be at least 1")
    return None if shard is None else (int(shard[0]), int(shard[1]))


class PointStore:
    """The journal of one bake writing ``output`` (an absolute .shprobe path)."""

    def __init__(self, output: str, shard: Optional[Tuple[int, int]] = None, merge_shards: Optional[int] = None,
                 restart: bool = False, log=print, messages=None):
        self.output = output
        self.shard = check_shards(shard, merge_shards)
        self.merge_shards = merge_shards
        self.restart = restart
        self.log = log
        self.messages = messages if messages is not None else []
        self.path = (local_journal_path(output) if self.shard is None
                     else shard_journal_path(output, *self.shard))
        self._writer = None
        self._lock = OutputLock(self.path)
        self._known = {}                    # journal key -> coefficients, from journals at open
        self._known_noise = {}
        self._kept = 0                      # points in the journal when it was closed
        self._seeds = set()                 # keys of an earlier bake's points taken by seed()

    @property
    def merging(self) -> bool:
        return self.merge_shards is not None

    @property
    def known_count(self) -> int:
        """Points the journals held when the bake opened them."""
        return len(self._known)

    @property
    def kept(self) -> int:
        """Points this bake's journal holds (also after :meth:`close`)."""
        return self._kept if self._writer is None else len(self._writer.values)

    def lock(self):
        """Take this journal's lock (output_lock.py): :class:`BakeError` naming the other bake's
        process when one holds it. Nothing is read or changed before."""
        try:
            self._lock.acquire()
        except OutputBusy as busy:
            what = self.output if self.shard is None else f"shard {self.shard[0]}/{self.shard[1]} of {self.output}"
            raise BakeError(f"Another bake is writing {what} ({busy.holder_text()}); wait for it to finish or "
                            "choose another output") from None
        except OSError as exc:
            raise BakeError(f"Cannot lock the output for this bake ({self._lock.path}): "
                            f"{exc.strerror or exc}") from exc

    @classmethod
    def locked(cls, *args, **kwargs) -> "PointStore":
        """A store whose lock is taken (:meth:`lock`): the first step of a volume bake."""
        store = cls(*args, **kwargs)
        store.lock()
        return store

    def unlock(self):
        """Free the lock (idempotent); after :meth:`close` and the journal's removal."""
        self._lock.release()

    def open(self, manifest: dict, coeff_count: int):
        """Open (or create at the first point) this bake's journal and load the points it and, for
        a merge or a shard, the shard journals already hold. A local journal of another bake is
        moved aside; a shard's or a merge's is an error."""
        check_replaceable(self.path, "journal")
        if self.restart and os.path.lexists(self.path):
            os.unlink(self.path)
        if self.shard is None and self.merge_shards is None and os.path.lexists(self.path):
            # A local journal of another bake (settings or scene changed since a cancel): kept one
            # generation back as <journal>.previous, and this bake starts from scratch. Shards and
            # merges refuse instead: mixing farm jobs of different scenes is a mistake to report.
            try:
                journal.read(self.path, expect_manifest=manifest)
            except journal.JournalError as exc:
                previous = sibling(self.path, ".previous")
                try:
                    os.replace(self.path, previous)
                except OSError as exc2:
                    raise BakeError(f"{exc}; and it cannot be moved aside: {exc2}") from exc2
                self.log(f"Schnee: {exc}: not resumed; it was moved to {previous} and this bake starts from "
                         "scratch")
                self.messages.append(f"An earlier, different bake's journal was moved to {previous}")
        try:
            self._writer = journal.Writer(self.path, manifest, coeff_count, shard=self.shard)
            self._known, self._known_noise = dict(self._writer.values), dict(self._writer.noise)
            others = []
            if self.merge_shards is not None:
                others = [shard_journal_path(self.output, k, self.merge_shards) for k in range(self.merge_shards)]
                missing = [p for p in others if not os.path.exists(p)]
                if missing:
                    raise BakeError(f"Cannot merge: {len(missing)} of {self.merge_shards} shard journal(s) "
                                    f"missing ({', '.join(os.path.basename(p) for p in missing)}); bake them "
                                    "first (--shard K/N)")
            elif self.shard is not None:
                k, n = self.shard
                others = [p for p in (shard_journal_path(self.output, j, n) for j in range(n) if j != k)
                          if os.path.exists(p)]
            if others:
                values, noise, _ = journal.merge(others, manifest)
                for key, v in values.items():
                    if key not in self._known:
                        self._known[key], self._known_noise[key] = v, noise[key]
        except journal.JournalError as exc:
            raise BakeError(f"{exc} (or bake with --restart to discard it)") from exc
        except OSError as exc:
            raise BakeError(f"Cannot open the bake journal {self.path}: {exc}") from exc
        if self._writer.torn_bytes:
            self.log(f"Schnee: the journal's last {self._writer.torn_bytes} bytes were an incomplete record "
                     "(a crash mid-write); cut off")

    def log_resume(self, keys, adaptive: bool):
        """Log how many of the first stage's points (their journal ``keys``) the journals hold."""
        if not self._known:
            return
        where = self.path if self.merge_shards is None else "the journals"
        if self._seeds:
            where += " and the previous bake's kept points"
        hits = sum(key in self._known for key in keys)
        more = f" in the first pass ({len(self._known)} points in the journals)" if adaptive else ""
        self.log(f"Schnee: resuming from {where}: {hits} of {len(keys)} probes already baked, "
                 f"{len(keys) - hits} to render{more}")

    def not_merged(self, pos) -> BakeError:
        """The error of a merge that finds the point at engine-space ``pos`` in no journal."""
        where = tuple(float(c) for c in scene_export.engine_to_blender(pos))
        return BakeError(f"Cannot merge: the point at Blender ({where[0]:.3f}, {where[1]:.3f}, "
                         f"{where[2]:.3f}) is in no shard journal (shards still running or failed); "
                         "re-run the incomplete shards, then merge again")

    def seed(self, values: dict, noise: dict) -> int:
        """Take points of an earlier bake as if rendered (region.py: a rebake's kept points outside
        its region); the journals' own points win. Returns how many were taken."""
        before = len(self._seeds)
        for key, v in values.items():
            if key not in self._known:
                self._known[key], self._known_noise[key] = v, noise.get(key, 0.0)
                self._seeds.add(key)
        return len(self._seeds) - before

    def seeded(self, key: bytes) -> bool:
        """The point was taken from an earlier bake by :meth:`seed`, not from this bake's journals."""
        return key in self._seeds

    def points(self):
        """(values, noise) of every point this bake holds: journals, seeds and renders."""
        values, noise = dict(self._known), dict(self._known_noise)
        if self._writer is not None:
            values.update(self._writer.values)
            noise.update(self._writer.noise)
        return values, noise

    def lookup(self, key: bytes):
        """(coeffs, noise) of a point the journals held at open, or None."""
        if key in self._known:
            return self._known[key], self._known_noise[key]
        return None

    def others(self, j: int) -> bool:
        """Point ``j`` of the current stage (its place in the stage's queue) is another shard's."""
        return self.shard is not None and j % self.shard[1] != self.shard[0]

    def append(self, key: bytes, coeffs, noise: float):
        try:
            self._writer.append(key, coeffs, noise)
        except OSError as exc:
            raise BakeError(f"Cannot write the bake journal {self.path}: {exc}") from exc

    def close(self, unlock: bool = False):
        """Close the journal (idempotent); ``unlock``: then free the lock, even if closing failed."""
        try:
            if self._writer is not None:
                self._kept = len(self._writer.values)
                self._writer.close()
                self._writer = None
        finally:
            if unlock:
                self.unlock()
