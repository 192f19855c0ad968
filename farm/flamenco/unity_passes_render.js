// SPDX-License-Identifier: GPL-3.0-or-later
//
// Flamenco job type "Unity Passes Render": renders frame chunks with the Unity Passes engine
// (`blender -b FILE -E UNITY_PASSES --render-output ... --render-frame A..B`), after Flamenco's
// stock "Simple Blender Render" job type. Install: copy this file into the `scripts/` folder
// next to the Flamenco Manager executable and restart the Manager (README: Render farms).
//
// Blender silently renders with EEVEE when `-E` names an engine it does not know, so:
// - the FIRST task, "check-unity-passes", only runs the engine check and every render task
//   depends on it: a farm whose worker lacks the add-on fails loudly before rendering anything;
// - every render command runs the same check again before its first frame (tasks may go to
//   other workers), so no worker without the add-on ever writes a frame.
// The check is farm/check_engine.py (setting `engine_check`: its path on the workers) or, when
// that setting is empty, the same check inline (UNITY_PASSES_CHECK below).

const ENGINE = "UNITY_PASSES";

// One-line form of farm/check_engine.py: exits 1 (with --python-exit-code 1) unless the engine is
// registered; on success Blender goes on with the rest of its command line.
const UNITY_PASSES_CHECK =
    "import sys, bpy; " +
    "ok = 'UNITY_PASSES' in {getattr(c, 'bl_idname', None) for c in bpy.types.RenderEngine.__subclasses__() " +
    "if getattr(c, 'is_registered', False)}; " +
    "print('Unity Passes check: the UNITY_PASSES render engine is registered' if ok else " +
    "'error: Unity Passes check: the UNITY_PASSES render engine is not registered in this Blender; " +
    "install and enable the Unity Passes extension on this worker (README: Render farms)', " +
    "file=sys.stdout if ok else sys.stderr); " +
    "ok or sys.exit(1)";

const JOB_TYPE = {
    label: "Unity Passes Render",
    description: "Render frames with the Unity Passes engine; fails first when a worker lacks the add-on",
    settings: [
        // Settings for artists to determine:
        { key: "frames", type: "string", required: true,
          eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
          evalInfo: { showLinkButton: true, description: "Scene frame range" },
          description: "Frame range to render. Examples: '47', '1-30', '3, 5-10, 47-327'" },
        { key: "chunk_size", type: "int32", default: 1, propargs: { min: 1 },
          description: "Number of frames to render in one Blender render task", visible: "submission" },

        // render_output_root + add_path_components determine the value of render_output_path.
        { key: "render_output_root", type: "string", subtype: "dir_path", required: true, visible: "submission",
          description: "Base directory of where render output is stored. Will have some job-specific parts appended to it" },
        { key: "add_path_components", type: "int32", required: true, default: 0, propargs: { min: 0, max: 32 },
          visible: "submission",
          description: "Number of path components of the current blend file to use in the render output path" },
        { key: "render_output_path", type: "string", subtype: "file_path", editable: false,
          eval: "str(Path(abspath(settings.render_output_root), last_n_dir_parts(settings.add_path_components), jobname, '{timestamp}', '######'))",
          description: "Final file path of where render output will be saved" },
        { key: "engine_check", type: "string", required: false, default: "", visible: "submission",
          description: "Path of farm/check_engine.py as the workers see it; empty: the same check inline" },

        // Automatically evaluated settings:
        { key: "blendfile", type: "string", required: true, description: "Path of the Blend file to render", visible: "web" },
        { key: "format", type: "string", required: true, eval: "C.scene.render.image_settings.file_format", visible: "web" },
        { key: "image_file_extension", type: "string", required: true, eval: "C.scene.render.file_extension",
          visible: "hidden", description: "File extension used when rendering images" },
    ],
};

// File formats that would cause rendering to video: not supported by this job type.
const videoFormats = ["FFMPEG", "AVI_RAW", "AVI_JPEG"];

function compileJob(job) {
    print("Unity Passes Render job submitted");
    const settings = job.settings;
    if (videoFormats.indexOf(settings.format) >= 0) {
        throw `This job type only renders images, and not "${settings.format}"`;
    }
    if (!(settings.chunk_size >= 1)) {
        throw `chunk_size must be 1 or more, not ${settings.chunk_size}`;
    }

    const renderOutput = renderOutputPath(job);
    // When the job is investigated later, show the actually-used render output:
    settings.render_output_path = renderOutput;
    const renderDir = path.dirname(renderOutput);

    const checkTask = authorCheckTask(settings);
    job.addTask(checkTask);
    for (const task of authorRenderTasks(settings, renderDir, renderOutput)) {
        task.addDependency(checkTask);
        job.addTask(task);
    }
}

// Do field replacement on the render output path.
function renderOutputPath(job) {
    const outputPath = job.settings.render_output_path;
    if (!outputPath) {
        throw "no render_output_path setting!";
    }
    return outputPath.replace(/{([^}]+)}/g, (match, group0) => {
        switch (group0) {
            case "timestamp":
                return formatTimestampLocal(job.created);
            default:
                return match;
        }
    });
}

// Blender arguments that exit with status 1 unless the Unity Passes engine is registered.
function checkArgs(settings) {
    if (settings.engine_check) {
        return ["--python-exit-code", "1", "--python", settings.engine_check];
    }
    return ["--python-exit-code", "1", "--python-expr", UNITY_PASSES_CHECK];
}

function authorCheckTask(settings) {
    const task = author.Task("check-unity-passes", "blender");
    task.addCommand(author.Command("blender-render", {
        exe: "{blender}",
        exeArgs: "{blenderArgs}",
        argsBefore: [],
        blendfile: settings.blendfile,
        args: checkArgs(settings),
    }));
    return task;
}

function authorRenderTasks(settings, renderDir, renderOutput) {
    const renderTasks = [];
    const chunks = frameChunker(settings.frames, settings.chunk_size);
    for (const chunk of chunks) {
        const task = author.Task(`render-${chunk}`, "blender");
        task.addCommand(author.Command("blender-render", {
            exe: "{blender}",
            exeArgs: "{blenderArgs}",
            argsBefore: [],
            blendfile: settings.blendfile,
            // Order matters: Blender applies its arguments left to right (engine, check, then render).
            args: ["--engine", ENGINE].concat(checkArgs(settings), [
                "--render-output", path.join(renderDir, path.basename(renderOutput)),
                "--render-format", settings.format,
                "--render-frame", chunk.replaceAll("-", ".."), // Blender's frame range notation
            ]),
        }));
        renderTasks.push(task);
    }
    return renderTasks;
}
