"""The C/C++ sources stay in the house format (.clang-format at the repository root)."""
import shutil
import subprocess

from conftest import REPO


def test_c_sources_match_clang_format():
    exe = shutil.which("clang-format")
    assert exe, "clang-format not installed (scripts/deps.sh installs it)"
    files = subprocess.run(["git", "ls-files", "*.c", "*.h", "*.cpp"], cwd=REPO, capture_output=True,
                           text=True, check=True).stdout.split()
    assert len(files) > 20, files  # the tree has ~50 C files: an empty list means git saw nothing
    proc = subprocess.run([exe, "--dry-run", "-Werror", *files], cwd=REPO, capture_output=True, text=True)
    assert proc.returncode == 0, "run `clang-format -i` on:\n" + "\n".join(
        sorted({line.split(":")[0] for line in proc.stderr.splitlines() if ": error:" in line}))
