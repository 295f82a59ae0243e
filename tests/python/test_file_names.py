"""The names a bake derives from its output stay within 255 bytes (addon/schnee_probes/file_names.py,
issue 31): unchanged where they fit, else shortened the same way every time, distinct per output,
in the output's folder; a journal beside the longest legal output name is created and reopened.
The limit is the file system's own: every name below is also created on disk here (tmpfs or ext4,
NAME_MAX 255), so a name the file system refuses fails the test. Runtime: < 1 s."""
import os

import numpy as np
import pytest

from schnee_probes import file_names, journal

PARTS = {"settings": "a" * 64}


def _name_max(folder):
    """The name limit as the file system of ``folder`` states it (the module assumes 255)."""
    return os.pathconf(folder, "PC_NAME_MAX")


def test_names_that_fit_are_unchanged(tmp_path):
    out = str(tmp_path / "probes.shprobe")
    assert file_names.sibling(out, ".journal") == out + ".journal"
    assert file_names.sibling(out, ".shard-3-of-8.journal") == out + ".shard-3-of-8.journal"
    tmp = file_names.temporary(out, "123-abcd")
    assert tmp == out + ".123-abcd.partial"
    # 255 bytes exactly is a legal name and stays as it is.
    name = "p" * (255 - len(".shprobe.journal")) + ".shprobe"
    assert file_names.sibling(str(tmp_path / name), ".journal") == str(tmp_path / name) + ".journal"


@pytest.mark.parametrize("length", [240, 247, 255])
@pytest.mark.parametrize("char", ["p", "é", "雪"], ids=["ascii", "2-byte", "3-byte"])
def test_long_names_are_shortened_to_the_limit(tmp_path, length, char):
    assert _name_max(tmp_path) == file_names.NAME_MAX
    stem = char * 300
    while len(os.fsencode(stem + ".shprobe")) > length:  # an output name of at most `length` bytes
        stem = stem[:-1]
    out = str(tmp_path / (stem + ".shprobe"))
    (tmp_path / (stem + ".shprobe")).write_bytes(b"SPHR")  # the output itself is a legal name
    for suffix in (".journal", ".shard-11-of-16.journal", ".journal.previous", ".farm"):
        got = file_names.sibling(out, suffix)
        name = os.path.basename(got)
        assert os.path.dirname(got) == str(tmp_path) and name.endswith(suffix)
        assert len(os.fsencode(name)) <= 255
        if len(os.fsencode(os.path.basename(out) + suffix)) <= 255:
            assert got == out + suffix
        else:
            # The start of the output's name (whole characters), "~" and 16 hex digits of its SHA-256.
            head, digest = name[:-len(suffix)].rsplit("~", 1)
            assert os.path.basename(out).startswith(head) and len(digest) == 16
            assert got == file_names.sibling(out, suffix)               # the same in every run
            assert got != file_names.sibling(out[:-9] + "q.shprobe", suffix)  # distinct per output
        with open(got, "w"):  # the file system takes it
            pass
    tmp = file_names.temporary(out)
    assert len(os.fsencode(os.path.basename(tmp))) <= 255 - file_names.WRITER_ROOM
    # Room for a native writer's own temporary name beside it (native/src/pb_common.c: ".tmp.XXXXXX").
    with open(tmp + ".tmp.XXXXXX", "w"):
        pass


def test_a_journal_beside_the_longest_output_name(tmp_path):
    # Before: the journal's temporary file ".<output>.journal.<pid>-<random>.partial" was over 255
    # bytes, and the first append failed with ENAMETOOLONG (the bake after its first render).
    out = str(tmp_path / ("p" * (255 - len(".shprobe")) + ".shprobe"))
    path = file_names.sibling(out, ".journal")
    manifest = journal.make_manifest(PARTS)
    key, value = journal.key_of((1.0, 2.0, 3.0)), np.arange(27.0).reshape(9, 3)
    with journal.Writer(path, manifest, 9) as w:
        w.append(key, value)
    with journal.Writer(path, manifest, 9) as w:  # reopened: resumed from it
        assert w.values[key].tobytes() == value.tobytes()
    assert sorted(os.listdir(tmp_path)) == [os.path.basename(path)]  # no temporary file left
