// SPDX-License-Identifier: Apache-2.0
// Flamenco 3.3 job type "crisp-render": renders a shot with Crisp on a render
// farm. The shot is split into contiguous chunks; each chunk is one task that
// runs `crisp render` on a worker, which renders the chunk's 1-sample frames in
// Blender, filters them with libcrisp and writes OUTDIR/input/ and
// OUTDIR/filtered/. A temporal method (taa, taa-improved, phlm) carries
// history from frame to frame, so each task first renders and filters
// `preroll` frames before its chunk (not written; never before the shot's
// first frame): the chunks then need no other chunk's history and run on any
// worker in any order, so they have no dependencies on each other.
//
// Install: copy this file into the `scripts` folder next to the
// flamenco-manager executable and restart the Manager (see flamenco/README.md
// and docs/farm.md). Flamenco's job-compiler API used here: the JOB_TYPE
// settings table, compileJob(job), author.Task(name, type),
// author.Command("exec", {exe, args}), task.addCommand, job.addTask. The
// Worker command `exec` exists since Flamenco 3.3 (so do settings' evalInfo).

const CRISP_METHODS = ["taa", "taa-improved", "phlm", "fxaa", "repair", "rsaa", "none"];
const CRISP_TEMPORAL_METHODS = ["taa", "taa-improved", "phlm"];
const CRISP_JITTERS = ["blackman-harris", "uniform"];
const CRISP_INPUT_CODECS = ["none", "piz", "zip"];

const JOB_TYPE = {
  label: "Crisp Render (chunked, with pre-roll)",
  description: "1-sample EEVEE frames anti-aliased by Crisp, rendered in chunks that warm their temporal history",
  settings: [
    // Filled in by the Flamenco add-on with the path of the submitted .blend file.
    { key: "blendfile", type: "string", required: true, visible: "web",
      description: "Path of the .blend file to render (as the workers see it)" },
    // The scene whose frames, method and panel the job takes (C.scene at submission): a .blend of several
    // scenes is rendered at that one, not at whichever it was saved with active (crisp render --scene-name).
    { key: "scene", type: "string", default: "",
      eval: "C.scene.name",
      evalInfo: { showLinkButton: true, description: "The submitting scene" },
      description: "Scene of the .blend to render (empty: the one the file was saved with active)" },
    { key: "frames", type: "string", required: true,
      eval: "f'{C.scene.frame_start}-{C.scene.frame_end}'",
      evalInfo: { showLinkButton: true, description: "Scene frame range" },
      description: "The shot: one contiguous range A-B (temporal history runs through it)" },
    // method, jitter and filter_params follow the scene's Crisp panel (scene.crisp, addon/crisp/properties.py):
    // Flamenco's add-on evaluates `eval` in the submitting Blender when the job is submitted, as long as
    // the setting's link button is on (its default; off, the field is edited by hand). Without the Crisp
    // add-on there is no scene.crisp and each gives its default: an expression that raised would stop
    // the submission with a Python error. A choice a newer add-on saved reads "" in this one's menu: the
    // job is refused naming it (compileJob), rather than run with crisp's default.
    { key: "method", type: "string", required: true, default: "taa", choices: CRISP_METHODS,
      eval: "getattr(getattr(C.scene, 'crisp', None), 'method', 'taa')",
      evalInfo: { showLinkButton: true, description: "Crisp panel's Method" },
      description: "Crisp filter to run on every frame" },
    { key: "chunk_size", type: "int32", default: 50, required: true,
      description: "Frames written per task" },
    { key: "preroll", type: "int32", default: 16, required: true,
      description: "Frames rendered and filtered before each chunk to warm the temporal history (not written)" },
    { key: "output_dir", type: "string", subtype: "dir_path", required: true,
      description: "Shared folder, an absolute path, for input/, filtered/ and one run_AAAA-BBBB.json per chunk" },
    { key: "resolution", type: "string", default: "",
      description: "Render size WxH (empty: the scene's)" },
    // crisp render --jitter: the add-on's panel offers both (Jitter); a resume keeps only frames made
    // with the same one.
    { key: "jitter", type: "string", default: "blackman-harris", choices: CRISP_JITTERS,
      eval: "getattr(getattr(C.scene, 'crisp', None), 'jitter_distribution', 'blackman-harris') or " +
        "'unknown to this add-on'",
      evalInfo: { showLinkButton: true, description: "Crisp panel's Jitter" },
      description: "Sub-pixel jitter of a temporal method's frames: blackman-harris (EEVEE's own pixel filter) or uniform (inside the pixel)" },
    // crisp render --input-codec: how the 1-sample renders kept in input/ are stored (all lossless: the
    // filtered frames are the same with each; a resume keeps frames stored with another).
    { key: "input_codec", type: "string", default: "none", choices: CRISP_INPUT_CODECS,
      eval: "getattr(getattr(C.scene, 'crisp', None), 'input_codec', 'none') or 'unknown to this add-on'",
      evalInfo: { showLinkButton: true, description: "Crisp panel's Input Codec" },
      description: "OpenEXR codec of the 1-sample renders kept in input/: none (fastest), piz or zip (about 4.5x " +
        "smaller)" },
    // The panel's parameters of its method that differ from the library's defaults, as a render from the
    // panel sends them (properties.py set_params_text). No lambda may name C: eval's locals are not its scope.
    { key: "filter_params", type: "string", default: "",
      eval: "getattr(getattr(C.scene, 'crisp', None), 'set_params_text', lambda: '')()",
      evalInfo: { showLinkButton: true, description: "Crisp panel's parameters of its method" },
      description: "Filter parameters, KEY=VALUE separated by spaces (see `crisp help METHOD`)" },
    { key: "crisp_exe", type: "string", default: "crisp", visible: "submission",
      description: "The crisp executable on the workers (a path, or a Manager variable such as {crisp})" },
    { key: "blender_exe", type: "string", default: "{blender}", visible: "hidden",
      description: "Blender on the workers, handed to crisp render --blender" },
  ],
};

function crispFail(message) {
  throw new Error("crisp-render: " + message);
}

// "A-B" or "A" (whitespace allowed; Blender's frames are >= 0) -> {first, last}; anything else is an error
// that names the setting, so the Manager shows why the job was refused.
function crispParseShot(text) {
  const found = /^\s*(\d+)\s*(?:-\s*(\d+)\s*)?$/.exec(String(text === undefined ? "" : text));
  if (!found)
    crispFail("setting 'frames' must be one contiguous range A-B (or a single frame A, frames >= 0), got '" +
              text + "'; submit one job per range");
  const first = parseInt(found[1], 10);
  const last = found[2] === undefined ? first : parseInt(found[2], 10);
  if (last < first) crispFail("setting 'frames' " + text + " is empty (end before start)");
  return { first: first, last: last };
}

function crispWholeNumber(settings, key, lowest) {
  const value = settings[key];
  if (typeof value !== "number" || !isFinite(value) || Math.floor(value) !== value || value < lowest)
    crispFail("setting '" + key + "' must be a whole number >= " + lowest + ", got '" + value + "'");
  return value;
}

function crispText(settings, key) {
  const value = settings[key];
  if (typeof value !== "string" || value.trim() === "") crispFail("setting '" + key + "' is empty");
  return value;
}

// The chunks of a shot: contiguous, in order, covering it once; each with the
// first frame of its pre-roll (the pre-roll never reaches before the shot).
function crispChunks(shot, chunkSize, preroll) {
  const chunks = [];
  for (let first = shot.first; first <= shot.last; first += chunkSize) {
    const last = Math.min(first + chunkSize - 1, shot.last);
    chunks.push({ first: first, last: last, prerollFirst: Math.max(shot.first, first - preroll) });
  }
  return chunks;
}

// filter_params as `crisp render --set` arguments: KEY=VALUE items separated by spaces. Their syntax is
// checked here, so a typo fails the submission rather than every task on the workers: the key a
// parameter name (letters, digits, '_'; `crisp help METHOD` lists them), the value present, without
// a second '=', list separators or quotes (the workers run crisp without a shell, so quotes would
// reach it as part of the value). Which names and values a method takes is the library's table
// (crisp render checks them on each worker before Blender starts); the Manager has no library.
function crispFilterParams(text) {
  const items = text === undefined || text === null ? [] : String(text).split(/\s+/).filter((kv) => kv !== "");
  for (const kv of items) {
    const eq = kv.indexOf("=");
    if (eq <= 0) crispFail("setting 'filter_params' needs KEY=VALUE items, got '" + kv + "'");
    const key = kv.slice(0, eq), value = kv.slice(eq + 1);
    const separator = /[,;]/.exec(kv);
    if (separator)
      crispFail("setting 'filter_params' items are separated by spaces, not '" + separator[0] + "': got '" + kv + "'");
    if (!/^[A-Za-z][A-Za-z0-9_]*$/.test(key))
      crispFail("setting 'filter_params' item '" + kv + "': '" + key + "' is no parameter name (e.g. feedbackMin; " +
                "`crisp help METHOD` lists them)");
    if (value === "") crispFail("setting 'filter_params' item '" + kv + "' has no value");
    if (value.indexOf("=") >= 0) crispFail("setting 'filter_params' item '" + kv + "' has more than one '='");
    if (/["'`]/.test(value))
      crispFail("setting 'filter_params' item '" + kv + "' is quoted: give the value without quotes (crisp gets " +
                "them as part of it)");
  }
  return items;
}

// A setting that names one of `choices`; "" when empty or absent (a job submitted before the setting
// existed), which leaves crisp render's default.
function crispOptionalChoice(settings, key, choices) {
  const value = settings[key] === undefined || settings[key] === "" ? "" : String(settings[key]);
  if (value !== "" && choices.indexOf(value) < 0)
    crispFail("setting '" + key + "' must be one of " + choices.join(", ") + ", got '" + value + "'");
  return value;
}

function compileJob(job) {
  const settings = job.settings;
  const shot = crispParseShot(settings.frames);
  const chunkSize = crispWholeNumber(settings, "chunk_size", 1);
  const method = crispText(settings, "method");
  if (CRISP_METHODS.indexOf(method) < 0)
    crispFail("setting 'method' must be one of " + CRISP_METHODS.join(", ") + ", got '" + method + "'");
  // A spatial method has no history to warm: its chunks need no pre-roll (a bad
  // setting is refused all the same, as flamenco/README.md says).
  const temporal = CRISP_TEMPORAL_METHODS.indexOf(method) >= 0;
  const prerollSetting = crispWholeNumber(settings, "preroll", 0);
  const preroll = temporal ? prerollSetting : 0;
  // Paths as typed, without the spaces around them (crisp render would read " /farm" as relative).
  const blendfile = crispText(settings, "blendfile").trim();
  const outputDir = crispText(settings, "output_dir").trim();
  // The workers must all write one shared folder: `crisp render -o` reads a
  // Blender-relative "//..." beside the copy of the .blend the worker opens
  // (job storage, a Shaman checkout), and any other relative path from the
  // worker's working folder. Blender's folder browser makes "//" paths by default.
  if (outputDir.startsWith("//"))
    crispFail("setting 'output_dir' '" + outputDir + "' is relative to the .blend file, which the workers open " +
              "from another folder: give the shared folder's absolute path");
  if (!/^(\/|\\\\|[A-Za-z]:[\\/]|\{)/.test(outputDir))
    crispFail("setting 'output_dir' '" + outputDir + "' is a relative path: give the shared folder's absolute " +
              "path (or a Manager variable such as {render}/...)");
  const crispExe = crispText(settings, "crisp_exe").trim();
  const resolution = settings.resolution ? String(settings.resolution).trim() : "";
  // crisp render takes each side from 4 (Blender's smallest) to 65536 (the library's largest).
  const size = /^(\d+)x(\d+)$/.exec(resolution);
  if (resolution !== "" && !(size && [size[1], size[2]].every((side) => +side >= 4 && +side <= 65536)))
    crispFail("setting 'resolution' must be WxH, each 4 to 65536 (e.g. 1920x1080), or empty, got '" + resolution + "'");
  const jitter = crispOptionalChoice(settings, "jitter", CRISP_JITTERS);
  const inputCodec = crispOptionalChoice(settings, "input_codec", CRISP_INPUT_CODECS);
  const params = crispFilterParams(settings.filter_params);

  const shotText = shot.first + "-" + shot.last;
  for (const chunk of crispChunks(shot, chunkSize, preroll)) {
    const args = ["render", "--scene", blendfile, "--method", method,
                  "--frames", chunk.first + "-" + chunk.last,
                  "--shot", shotText, "--preroll", String(chunk.first - chunk.prerollFirst),
                  // A task the Manager re-queues (worker lost, task failed) continues where it stopped.
                  "--resume",
                  // The job's method, jitter, input_codec and filter_params took the panel when it was submitted (or
                  // were typed): they alone say what runs, not the panel saved in the .blend.
                  "--no-panel", "-o", outputDir];
    if (settings.scene) args.push("--scene-name", String(settings.scene));  // absent: a job of an older job type
    if (settings.blender_exe) args.push("--blender", String(settings.blender_exe));
    if (resolution !== "") args.push("--resolution", resolution);
    if (jitter !== "") args.push("--jitter", jitter);
    // Not "none", crisp render's default: a job that keeps it runs on workers whose crisp predates the option.
    if (inputCodec !== "" && inputCodec !== "none") args.push("--input-codec", inputCodec);
    for (const kv of params) args.push("--set", kv);
    const task = author.Task("crisp-" + chunk.first + "-" + chunk.last, "blender");
    task.addCommand(author.Command("exec", { exe: crispExe, args: args }));
    job.addTask(task);
  }
}
