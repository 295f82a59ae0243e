// SPDX-License-Identifier: GPL-3.0-or-later
// Flamenco job type "Schnee Probes Bake" (docs/farm.md): per placement stage one Blender task per
// shard (bake.py -- --shard K/N), each stage after the previous one, then one merge task
// (--merge-shards N) after the last stage that writes the .shprobe files. Shards resume from their journals, so a task that Flamenco
// re-queues after a failure re-renders only what it had not finished. Install: copy this file into
// the `scripts/` folder next to the Flamenco Manager executable and restart the Manager.

const JOB_TYPE = {
    label: "Schnee Probes Bake",
    description: "Bake Schnee SH light probes in shards, then merge them",
    settings: [
        {
            key: "shards",
            type: "int32",
            default: 4,
            required: true,
            visible: "submission",
            description: "Number of shards (tasks that bake in parallel)",
        },
        {
            key: "stages",
            type: "int32",
            default: 17,
            required: true,
            visible: "submission",
            description: "Placement stages: 3 x floor(log2(Max / Min Cell Size)) + 2 for Adaptive placement " +
                "(17 at the defaults 0.5 / 16 m; bake.py --farm prints it), 1 for the geometry octree. " +
                "More than needed costs only a quick task per shard.",
        },
        {
            key: "bake_py",
            type: "string",
            subtype: "file_path",
            required: true,
            visible: "submission",
            description: "bake.py inside the installed schnee_probes add-on, as the Workers see it",
        },
        {
            key: "bake_args",
            type: "string",
            default: "",
            visible: "submission",
            description: "bake.py options shared by every task, e.g. '--output //sh_coeffs/probes.shprobe --samples 64'",
        },
        // Set by the submission add-on from the saved file.
        { key: "blendfile", type: "string", required: true, visible: "web", description: "Path of the .blend file" },
    ],
};

// Splits bake_args on whitespace; quotes group words ('a b' or "a b"), as a shell would.
function splitArgs(text) {
    const out = [];
    const re = /"([^"]*)"|'([^']*)'|(\S+)/g;
    let m;
    while ((m = re.exec(text || "")) !== null) out.push(m[1] !== undefined ? m[1] : m[2] !== undefined ? m[2] : m[3]);
    return out;
}

function bakeCommand(settings, extra) {
    return author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: [],
        blendfile: settings.blendfile,
        args: ["-P", settings.bake_py, "--"].concat(splitArgs(settings.bake_args), extra),
    });
}

function compileJob(job) {
    const settings = job.settings;
    const n = settings.shards;
    const stages = settings.stages;
    if (!(n >= 1)) throw `shards must be at least 1, not ${n}`;
    if (!(stages >= 1)) throw `stages must be at least 1, not ${stages}`;
    // One round of shard tasks per placement stage, each round after every task of the round
    // before: a stage's points depend on all values of the previous one (docs/farm.md).
    let previous = [];
    for (let s = 0; s < stages; s++) {
        const round = [];
        for (let k = 0; k < n; k++) {
            const task = author.Task(`stage-${s + 1}-shard-${k}-of-${n}`, "blender");
            task.addCommand(bakeCommand(settings, ["--shard", `${k}/${n}`]));
            for (const t of previous) task.addDependency(t);
            job.addTask(task);
            round.push(task);
        }
        previous = round;
    }
    const merge = author.Task("merge", "blender");
    merge.addCommand(bakeCommand(settings, ["--merge-shards", `${n}`]));
    for (const t of previous) merge.addDependency(t);
    job.addTask(merge);
}
