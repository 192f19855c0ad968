// A stand-in for Flamenco Manager's job-compiler globals (author, path, print, frameChunker,
// formatTimestampLocal), enough to run a job type script under node and print what it authors.
//
//   node tests/farm/author_stub.js JOBTYPE.js JOB.json   → stdout: one JSON object
//   {"job_type": {...JOB_TYPE}, "settings": {...after compile}, "tasks": [{name, type, commands, dependencies}]}
// A script that throws prints {"error": "..."} and exits 3.
"use strict";
const fs = require("fs");
const nodePath = require("path");
const vm = require("vm");

// Flamenco's frame chunker (internal/manager/job_compilers/frame_chunker.go): explode "1-10,20"
// (or "1..10") into sorted unique frames, cut into chunks of chunkSize, merge each chunk back
// into "A-B" runs joined by "," (two consecutive frames as "A,B").
function frameChunker(frameRange, chunkSize) {
    frameRange = String(frameRange).trim();
    if (!frameRange) throw `invalid range "${frameRange}": empty range`;
    if (!(chunkSize >= 1)) throw `invalid chunk size, must be positive number: ${chunkSize}`;
    const frames = new Set();
    for (let part of frameRange.split(",")) {
        part = part.trim();
        const m = part.match(/^(-?\d+)(?:(?:-|\.\.)(-?\d+))?$/);
        if (!m) throw `invalid range "${frameRange}": ${part}`;
        const a = parseInt(m[1], 10), b = m[2] === undefined ? a : parseInt(m[2], 10);
        for (let f = a; f <= b; f++) frames.add(f);
    }
    const list = [...frames].sort((x, y) => x - y);
    const chunks = [];
    for (let i = 0; i < list.length; i += chunkSize) chunks.push(merge(list.slice(i, i + chunkSize)));
    return chunks;
}

function merge(frames) {
    const ranges = [];
    const add = (a, b) => {
        if (a === b) ranges.push(`${a}`);
        else if (a + 1 === b) ranges.push(`${a}`, `${b}`);
        else ranges.push(`${a}-${b}`);
    };
    let start = frames[0], prev = frames[0];
    for (const f of frames) {
        if (f > prev + 1) { add(start, prev); start = f; }
        prev = f;
    }
    add(start, prev);
    return ranges.join(",");
}

class Task {
    constructor(name, type) { this.name = name; this.type = type; this.commands = []; this.dependencies = []; }
    addCommand(command) { this.commands.push(command); }
    addDependency(task) {
        if (!(task instanceof Task)) throw "addDependency: not a task";
        this.dependencies.push(task);
    }
}

const author = {
    Task: (name, type) => new Task(name, type),
    Command: (type, parameters) => ({ type, parameters }),
};

const flamencoPath = {
    join: (...parts) => nodePath.posix.join(...parts),
    dirname: (p) => nodePath.posix.dirname(p),
    basename: (p) => nodePath.posix.basename(p),
    stem: (p) => nodePath.posix.parse(p).name,
};

function main() {
    const [scriptFile, jobFile] = process.argv.slice(2);
    const jobIn = JSON.parse(fs.readFileSync(jobFile, "utf8"));
    const tasks = [];
    const job = {
        settings: jobIn.settings,
        created: new Date(jobIn.created || "2025-01-02T03:04:05Z"),
        addTask: (task) => {
            if (!(task instanceof Task)) throw "addTask: not a task";
            tasks.push(task);
        },
    };
    const context = vm.createContext({
        author, path: flamencoPath, frameChunker,
        print: (...args) => process.stderr.write(args.map(String).join(" ") + "\n"),
        formatTimestampLocal: (date) => date.toISOString().slice(0, 19).replace(/[-:]/g, "").replace("T", "-"),
    });
    vm.runInContext(fs.readFileSync(scriptFile, "utf8") + "\n;this.JOB_TYPE = JOB_TYPE; this.compileJob = compileJob;",
                    context, { filename: scriptFile });
    try {
        context.compileJob(job);
    } catch (err) {
        process.stdout.write(JSON.stringify({ error: String(err) }) + "\n");
        process.exit(3);
    }
    const out = {
        job_type: context.JOB_TYPE,
        settings: job.settings,
        tasks: tasks.map((t) => ({
            name: t.name, type: t.type, commands: t.commands,
            dependencies: t.dependencies.map((d) => d.name),
        })),
    };
    process.stdout.write(JSON.stringify(out) + "\n");
}

main();
