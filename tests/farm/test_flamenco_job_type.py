"""The Flamenco job type (addon/schnee_probes/flamenco/schnee_probes_bake.js; docs/farm.md). Flamenco
is not packaged for Debian and its Manager does not run here, so this runs the job type's
compileJob in Node with a small stand-in for the Manager's `author` API (Task, Command,
addCommand, addDependency, job.addTask — the names Flamenco's own job types use) and checks the
tasks it authors: per stage one `blender-render` task per shard with bake.py's --shard K/N, each
stage after the previous, then a merge task with --merge-shards N after the last stage; bad input is refused. What the real Manager does
with them is not tested here (said in docs/farm.md)."""
import json
import shutil
import subprocess

import pytest

from conftest import REPO

JS = REPO / "addon" / "schnee_probes" / "flamenco" / "schnee_probes_bake.js"

HARNESS = r"""
const fs = require("fs");
const src = fs.readFileSync(process.argv[2], "utf8");
const author = {
  Task: (name, type) => ({ name, type, commands: [], deps: [],
    addCommand(c) { this.commands.push(c); }, addDependency(t) { this.deps.push(t.name); } }),
  Command: (type, params) => ({ type, params }),
};
const job = { settings: JSON.parse(process.argv[3]), tasks: [], addTask(t) { this.tasks.push(t); } };
try {
  new Function("author", src + "\ncompileJob(arguments[1]); return JOB_TYPE;")(author, job);
  console.log(JSON.stringify({ tasks: job.tasks }));
} catch (e) { console.log(JSON.stringify({ error: String(e) })); }
"""


def _compile(tmp_path, settings):
    node = shutil.which("node") or shutil.which("nodejs")
    if node is None:
        pytest.fail("node is not installed (scripts/deps.sh installs nodejs)")
    h = tmp_path / "harness.js"
    h.write_text(HARNESS)
    out = subprocess.run([node, str(h), str(JS), json.dumps(settings)], capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def test_one_task_per_shard_and_stage_then_the_merge(tmp_path):
    res = _compile(tmp_path, {"shards": 3, "stages": 2, "bake_py": "/opt/addons/schnee_probes/bake.py",
                              "bake_args": "--samples 64 --output '//sh coeffs/probes.shprobe'",
                              "blendfile": "/farm/scene.blend"})
    tasks = res["tasks"]
    first = ["stage-1-shard-0-of-3", "stage-1-shard-1-of-3", "stage-1-shard-2-of-3"]
    second = ["stage-2-shard-0-of-3", "stage-2-shard-1-of-3", "stage-2-shard-2-of-3"]
    assert [t["name"] for t in tasks] == first + second + ["merge"]
    for i, t in enumerate(tasks[:6]):
        (cmd,) = t["commands"]
        assert t["type"] == "blender" and cmd["type"] == "blender-render"
        assert t["deps"] == ([] if i < 3 else first)  # a stage after every task of the one before
        assert cmd["params"]["blendfile"] == "/farm/scene.blend"
        assert cmd["params"]["args"] == ["-P", "/opt/addons/schnee_probes/bake.py", "--", "--samples", "64",
                                         "--output", "//sh coeffs/probes.shprobe", "--shard", f"{i % 3}/3"]
    assert tasks[6]["commands"][0]["params"]["args"][-2:] == ["--merge-shards", "3"]
    assert tasks[6]["deps"] == second


def test_zero_shards_is_refused(tmp_path):
    res = _compile(tmp_path, {"shards": 0, "stages": 1, "bake_py": "b.py", "bake_args": "", "blendfile": "x.blend"})
    assert res == {"error": "shards must be at least 1, not 0"}
    res = _compile(tmp_path, {"shards": 2, "stages": 0, "bake_py": "b.py", "bake_args": "", "blendfile": "x.blend"})
    assert res == {"error": "stages must be at least 1, not 0"}
