// SPDX-License-Identifier: Apache-2.0
// The Flamenco job type flamenco/crisp-render.js under Node.js (18 or later):
// the script runs in a fresh context with a stub of Flamenco's job-compiler API
// (author.Task, author.Command, task.addCommand/addDependency, job.addTask,
// print), as the Manager's JavaScript engine runs it, and the tasks it makes
// are checked: chunk frame ranges cover the shot once and in order, pre-roll
// frames, the crisp command lines, no dependencies between chunks, and clear
// errors for bad settings. Usage: node test_job_type.mjs [path/to/crisp-render.js]
import assert from "node:assert/strict";
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";
import vm from "node:vm";

const here = path.dirname(fileURLToPath(import.meta.url));
const scriptPath = process.argv[2] || path.join(here, "..", "..", "flamenco", "crisp-render.js");
const source = fs.readFileSync(scriptPath, "utf8");

// Flamenco's API, as far as a job compiler sees it: tasks carry their commands
// and dependencies; the job collects tasks.
function flamencoStub() {
  const author = {
    Task(name, type) {
      return {
        name, type, commands: [], dependencies: [],
        addCommand(cmd) { this.commands.push(cmd); },
        addDependency(task) { this.dependencies.push(task); },
      };
    },
    Command(name, parameters) { return { name, parameters }; },
  };
  return { author, print: () => {} };
}

// Loads the script (a fresh context per job, like the Manager) and compiles a
// job whose settings are the JOB_TYPE defaults overridden by `settings`.
function compile(settings) {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context, { filename: scriptPath });
  const defaults = {};
  for (const s of context.__jobType.settings) if (s.default !== undefined) defaults[s.key] = s.default;
  const job = { settings: { ...defaults, ...settings }, tasks: [], addTask(t) { this.tasks.push(t); } };
  context.compileJob(job);
  return job.tasks;
}

// The value following `flag` in an argument list (undefined if absent).
function flagValue(args, flag) {
  const i = args.indexOf(flag);
  return i < 0 ? undefined : args[i + 1];
}

function range(text) {
  const [a, b] = text.split("-").map(Number);
  return { first: a, last: b };
}

const base = { blendfile: "/farm/shots/sh010.blend", frames: "1-100", output_dir: "/farm/out/sh010",
               method: "taa", chunk_size: 30, preroll: 16 };
const tests = [];
const test = (name, fn) => tests.push({ name, fn });

test("JOB_TYPE declares every setting compileJob reads, with valid types", () => {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context);
  const keys = context.__jobType.settings.map((s) => s.key);
  for (const k of ["blendfile", "frames", "method", "chunk_size", "preroll", "output_dir", "crisp_exe"])
    assert.ok(keys.includes(k), "missing setting " + k);
  for (const s of context.__jobType.settings) {
    assert.ok(["string", "int32", "float", "bool"].includes(s.type), s.key + ": type " + s.type);
    if (s.visible !== undefined) assert.ok(["visible", "hidden", "submission", "web"].includes(s.visible), s.key);
  }
  assert.equal(typeof context.compileJob, "function");
});

test("chunks cover the shot once, in order, with pre-roll clamped at the shot's start", () => {
  const tasks = compile(base);
  assert.equal(tasks.length, 4);  // 1-30, 31-60, 61-90, 91-100
  let next = 1;
  for (const t of tasks) {
    assert.equal(t.type, "blender");
    assert.equal(t.commands.length, 1);
    const { name, parameters } = t.commands[0];
    assert.equal(name, "exec");
    assert.equal(parameters.exe, "crisp");
    const args = parameters.args;
    assert.ok(args.every((a) => typeof a === "string"), "all arguments are strings");
    assert.equal(args[0], "render");
    const chunk = range(flagValue(args, "--frames"));
    assert.equal(chunk.first, next);
    assert.ok(chunk.last >= chunk.first && chunk.last - chunk.first + 1 <= 30);
    next = chunk.last + 1;
    assert.equal(t.name, `crisp-${chunk.first}-${chunk.last}`);
    assert.equal(Number(flagValue(args, "--preroll")), Math.min(16, chunk.first - 1));
    assert.equal(flagValue(args, "--shot"), "1-100");
    assert.equal(flagValue(args, "--scene"), base.blendfile);
    assert.equal(flagValue(args, "--method"), "taa");
    assert.equal(flagValue(args, "-o"), base.output_dir);
    assert.equal(flagValue(args, "--blender"), "{blender}");  // the Manager's variable, expanded per worker
    assert.ok(args.includes("--resume"), "a re-queued task resumes");
    assert.ok(args.includes("--no-panel"), "the job's settings, not the .blend's panel, say what runs");
    assert.deepEqual(t.dependencies, [], "chunks are independent: pre-roll replaces the previous chunk's history");
  }
  assert.equal(next, 101);
});

test("a chunk larger than the shot gives one task without pre-roll", () => {
  const tasks = compile({ ...base, frames: "5-12", chunk_size: 50 });
  assert.equal(tasks.length, 1);
  const args = tasks[0].commands[0].parameters.args;
  assert.equal(flagValue(args, "--frames"), "5-12");
  assert.equal(flagValue(args, "--preroll"), "0");
  assert.equal(flagValue(args, "--shot"), "5-12");
});

test("pre-roll longer than the frames before a chunk reaches back to the shot's first frame only", () => {
  const tasks = compile({ ...base, frames: "101-110", chunk_size: 3, preroll: 5 });
  const got = Array.from(tasks, (t) => [flagValue(t.commands[0].parameters.args, "--frames"),
                                Number(flagValue(t.commands[0].parameters.args, "--preroll"))]);
  assert.deepEqual(got, [["101-103", 0], ["104-106", 3], ["107-109", 5], ["110-110", 5]]);
});

test("a single frame, frame 0 and spaces are accepted", () => {
  assert.equal(flagValue(compile({ ...base, frames: " 7 " })[0].commands[0].parameters.args, "--frames"), "7-7");
  const tasks = compile({ ...base, frames: "0 - 7", chunk_size: 4, preroll: 2 });
  assert.deepEqual(Array.from(tasks, (t) => flagValue(t.commands[0].parameters.args, "--frames")), ["0-3", "4-7"]);
  assert.equal(flagValue(tasks[1].commands[0].parameters.args, "--preroll"), "2");
});

// The methods `crisp render` knows and those it warms with a pre-roll, as the add-on's plan.py
// (which crisp render runs) lists them: METHOD_PASSES' keys and TEMPORAL_METHODS.
function addonMethods() {
  const plan = fs.readFileSync(path.join(here, "..", "..", "addon", "crisp", "plan.py"), "utf8");
  const passes = /^METHOD_PASSES = \{\n([\s\S]*?)^\}/m.exec(plan);
  const temporal = /^TEMPORAL_METHODS = \(([^)]*)\)/m.exec(plan);
  assert.ok(passes && temporal, "plan.py: METHOD_PASSES or TEMPORAL_METHODS not found");
  const names = (text, re) => Array.from(text.matchAll(re), (m) => m[1]).sort();
  return { all: names(passes[1], /^\s*"([^"]+)":/gm), temporal: names(temporal[1], /"([^"]+)"/g) };
}

test("the method choices are crisp render's, and every temporal one gets a pre-roll", () => {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context);
  const choices = context.__jobType.settings.find((s) => s.key === "method").choices;
  const { all, temporal } = addonMethods();
  assert.deepEqual(Array.from(choices).sort(), all);
  for (const method of all) {
    const prerolls = compile({ ...base, method }).map((t) => Number(flagValue(t.commands[0].parameters.args, "--preroll")));
    // chunks 1-30, 31-60, 61-90, 91-100 with a pre-roll of 16 for a temporal method, none for a spatial one
    assert.deepEqual(prerolls, temporal.includes(method) ? [0, 16, 16, 16] : [0, 0, 0, 0], method);
  }
});

// Settings whose choices are a tuple of render.py: [setting, tuple, crisp render's default, another, flag].
// crisp render's default as the setting's: a job's frames equal a plain run's.
const RENDER_CHOICES = [
  ["jitter", "JITTER_DISTRIBUTIONS", "blackman-harris", "uniform", "--jitter"],
  ["input_codec", "INPUT_CODECS", "none", "piz", "--input-codec"],
];

test("the jitter and input codec choices are crisp render's and reach its command line", () => {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context);
  const render = fs.readFileSync(path.join(here, "..", "..", "addon", "crisp", "render.py"), "utf8");
  for (const [key, tuple, fallback, other, flag] of RENDER_CHOICES) {
    const setting = context.__jobType.settings.find((s) => s.key === key);
    const known = new RegExp("^" + tuple + " = \\(([^)]*)\\)", "m").exec(render);
    assert.ok(known, "render.py: " + tuple + " not found");
    assert.deepEqual(Array.from(setting.choices), Array.from(known[1].matchAll(/"([^"]+)"/g), (m) => m[1]), key);
    assert.equal(setting.default, fallback, key);
    for (const t of compile({ ...base, [key]: other }))
      assert.equal(flagValue(t.commands[0].parameters.args, flag), other, key);
    // A job submitted before the setting existed: no flag, crisp render's default.
    assert.equal(flagValue(compile({ ...base, [key]: undefined })[0].commands[0].parameters.args, flag), undefined,
                 key);
  }
  // Uncompressed inputs, crisp render's default, pass no flag: such jobs run on workers of an older crisp.
  assert.equal(flagValue(compile({ ...base, input_codec: "none" })[0].commands[0].parameters.args, "--input-codec"),
               undefined);
});

test("method, jitter, input_codec and filter_params follow the scene's Crisp panel at submission", () => {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context);
  const settings = Object.fromEntries(context.__jobType.settings.map((s) => [s.key, s]));
  // Flamenco's add-on evaluates `eval` at submission only while the setting is linked (evalInfo.showLinkButton,
  // linked by default); without it, only when the artist presses the setting's button.
  const panel = { method: "method", jitter: "jitter_distribution", input_codec: "input_codec",
                  filter_params: "set_params_text" };
  for (const [key, attribute] of Object.entries(panel)) {
    const s = settings[key];
    assert.equal(typeof s.eval, "string", key + ": no eval");
    assert.ok(s.eval.includes("getattr(C.scene, 'crisp', None)"), key + ": " + s.eval);
    assert.ok(s.eval.includes("'" + attribute + "'"), key + ": " + s.eval);
    assert.equal(s.evalInfo && s.evalInfo.showLinkButton, true, key);
    assert.ok(s.evalInfo.description, key);
    // Without the Crisp add-on (no scene.crisp) the expression gives the setting's default; a choice a newer
    // add-on saved (read as "") gives a value compileJob refuses.
    const fallback = /'([^']*)'\)(?:\(\))?(?: or '([^']*)')?$/.exec(s.eval);
    assert.ok(fallback, key + ": no fallback in " + s.eval);
    assert.equal(fallback[1], s.default, key);
    if (fallback[2] !== undefined) assert.ok(s.choices && !s.choices.includes(fallback[2]), key);
  }
  // The panel's parameters come from the add-on's own conversion, a method of its scene settings.
  const properties = fs.readFileSync(path.join(here, "..", "..", "addon", "crisp", "properties.py"), "utf8");
  const settingsClass = /^class CrispSettings\([\s\S]*?(?=^\S)/m.exec(properties);
  assert.ok(settingsClass && /^    def set_params_text\(self\):/m.test(settingsClass[0]),
            "properties.py: CrispSettings.set_params_text not found");
  assert.ok(/jitter_distribution: bpy\.props\.EnumProperty/.test(settingsClass[0]), "properties.py: jitter_distribution");
  assert.ok(/input_codec: bpy\.props\.EnumProperty/.test(settingsClass[0]), "properties.py: input_codec");
});

test("the submitting scene is the one rendered", () => {
  const context = vm.createContext(flamencoStub());
  vm.runInContext(source + "\n;globalThis.__jobType = JOB_TYPE;", context);
  const setting = context.__jobType.settings.find((s) => s.key === "scene");
  assert.ok(setting, "no scene setting");
  assert.equal(setting.eval, "C.scene.name");
  assert.equal(setting.evalInfo && setting.evalInfo.showLinkButton, true);
  for (const t of compile({ ...base, scene: "Shot 2" }))
    assert.equal(flagValue(t.commands[0].parameters.args, "--scene-name"), "Shot 2");
  // Empty, or a job submitted before the setting existed: the file's active scene, as before.
  for (const scene of ["", undefined])
    assert.equal(flagValue(compile({ ...base, scene })[0].commands[0].parameters.args, "--scene-name"), undefined);
});

test("spatial methods get no pre-roll (no history to warm)", () => {
  for (const method of ["fxaa", "repair", "rsaa", "none"])
    for (const t of compile({ ...base, method }))
      assert.equal(flagValue(t.commands[0].parameters.args, "--preroll"), "0", method);
});

test("optional settings reach the command line", () => {
  assert.equal(flagValue(compile({ ...base, frames: "1-4", resolution: "4x65536" })[0].commands[0].parameters.args,
                         "--resolution"), "4x65536");
  const [t] = compile({ ...base, frames: "1-4", resolution: "640x360", filter_params: "feedbackMin=0.8  sharpen=0.2",
                        crisp_exe: "/opt/crisp/bin/crisp" });
  const args = t.commands[0].parameters.args;
  assert.equal(t.commands[0].parameters.exe, "/opt/crisp/bin/crisp");
  assert.equal(flagValue(args, "--resolution"), "640x360");
  assert.deepEqual(Array.from(args).filter((a, i) => args[i - 1] === "--set"), ["feedbackMin=0.8", "sharpen=0.2"]);
});

test("filter_params of every value kind pass as typed; blank ones pass none", () => {
  // Each kind crisp render --set takes (the add-on's panel writes them so: native.param_text): a float,
  // an exponent, a negative number, a bool, a choice with a '-' in it, an int.
  const items = ["feedbackMin=0.8", "holdRelease=1e-3", "sharpen=-0.5", "footprintBox=false",
                 "modelFetch=catmull-rom", "holdPeriod=16"];
  const [t] = compile({ ...base, frames: "1-4", filter_params: " " + items.join(" \t ") + " " });
  const args = t.commands[0].parameters.args;
  assert.deepEqual(Array.from(args).filter((a, i) => args[i - 1] === "--set"), items);
  for (const blank of ["", "  ", "\t"]) {  // "  " was refused as an item '' without '='
    const [u] = compile({ ...base, frames: "1-4", filter_params: blank });
    assert.ok(!u.commands[0].parameters.args.includes("--set"), JSON.stringify(blank));
  }
});

test("absolute output folders and Manager variables are accepted", () => {
  for (const dir of ["/farm/out/sh010", "{render}/sh010", "C:\\farm\\out", "D:/farm/out", "\\\\server\\share\\out"])
    assert.equal(flagValue(compile({ ...base, frames: "1-2", output_dir: dir })[0].commands[0].parameters.args, "-o"), dir);
});

test("spaces around the paths are not passed on", () => {
  const [t] = compile({ ...base, frames: "1-2", blendfile: " /farm/shots/sh010.blend ", output_dir: " /farm/out/sh010\t",
                        crisp_exe: " /opt/crisp/bin/crisp " });
  const args = t.commands[0].parameters.args;
  assert.equal(flagValue(args, "--scene"), "/farm/shots/sh010.blend");
  assert.equal(flagValue(args, "-o"), "/farm/out/sh010");  // " /farm/out" is a relative path to crisp render
  assert.equal(t.commands[0].parameters.exe, "/opt/crisp/bin/crisp");
});

test("bad settings raise an error naming the setting", () => {
  const bad = [
    [{ frames: "1-10,20-30" }, /'frames' must be one contiguous range/],
    [{ frames: "20-10" }, /'frames' 20-10 is empty/],
    [{ frames: "-4-3" }, /'frames' must be one contiguous range/],
    [{ frames: "" }, /'frames'/],
    [{ chunk_size: 0 }, /'chunk_size' must be a whole number >= 1/],
    [{ chunk_size: 2.5 }, /'chunk_size'/],
    [{ preroll: -1 }, /'preroll' must be a whole number >= 0/],
    [{ preroll: -1, method: "fxaa" }, /'preroll' must be a whole number >= 0/],  // refused though unused
    [{ method: "smaa" }, /'method' must be one of/],
    [{ output_dir: "  " }, /'output_dir' is empty/],
    // Blender's folder browser writes "//out/" (relative to the .blend); the workers open a copy elsewhere.
    [{ output_dir: "//out/" }, /'output_dir' '\/\/out\/' is relative to the \.blend file/],
    [{ output_dir: "out/sh010" }, /'output_dir' 'out\/sh010' is a relative path/],
    [{ blendfile: undefined }, /'blendfile' is empty/],
    [{ resolution: "big" }, /'resolution' must be WxH/],
    [{ resolution: "2x2" }, /'resolution' must be WxH, each 4 to 65536/],  // crisp render refuses it on every worker
    [{ resolution: "640x65537" }, /'resolution' must be WxH, each 4 to 65536/],
    [{ filter_params: "sharpen" }, /'filter_params' needs KEY=VALUE/],
    // Syntax the workers' crisp render would refuse, every task of the job: refused at submission.
    [{ filter_params: "sharpen=" }, /'filter_params' item 'sharpen=' has no value/],
    [{ filter_params: "feedbackMin=0.8,sharpen=0.2" }, /'filter_params' items are separated by spaces, not ','/],
    [{ filter_params: "feedbackMin=0.8;sharpen=0.2" }, /'filter_params' items are separated by spaces, not ';'/],
    [{ filter_params: "sharpen=0.2=0.3" }, /'filter_params' item 'sharpen=0.2=0.3' has more than one '='/],
    [{ filter_params: "sharpen='0.2'" }, /'filter_params' item 'sharpen='0.2'' is quoted/],
    [{ filter_params: 'sharpen="0.2"' }, /is quoted/],
    [{ filter_params: "feedback-min=0.8" }, /'filter_params' item 'feedback-min=0.8': 'feedback-min' is no parameter name/],
    [{ filter_params: "--set=0.8" }, /is no parameter name/],
    [{ jitter: "gauss" }, /'jitter' must be one of blackman-harris, uniform/],
    [{ input_codec: "dwaa" }, /'input_codec' must be one of none, piz, zip/],
  ];
  for (const [override, message] of bad)
    assert.throws(() => compile({ ...base, ...override }), message, JSON.stringify(override));
});

let failed = 0;
for (const { name, fn } of tests) {
  try {
    fn();
    console.log("ok   " + name);
  } catch (e) {
    failed++;
    console.log("FAIL " + name + "\n" + (e && e.stack ? e.stack : e));
  }
}
console.log(`${tests.length - failed}/${tests.length} passed`);
process.exit(failed ? 1 : 0);
