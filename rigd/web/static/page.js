// rigd operator page: refreshes the server-rendered parts from GET /ui/live (only the parts that changed come
// back) and sends the buttons' requests to the JSON API with fetch(). The bearer token (when the service has
// one) lives in this tab's sessionStorage. The viewer shows a version's overlays or a dataset's captured pairs,
// with zoom and pan at full resolution and a before/after switch.
"use strict";

const TOKEN_KEY = "rigd-token";
const FOLLOW_KEY = "rigd-followed";  // the followed job, kept in the tab: a reload mid-job still announces its end
const REQUEST_TIMEOUT_MS = 8000;  // longer without an answer: the service counts as unreachable
const tokenRequired = document.body.dataset.tokenRequired === "true";
const versionsPage = Number(document.body.dataset.versionsPage) || 10;
const hashes = {};             // part name -> hash of the HTML shown (sent back: unchanged parts are not resent)
let shownVersions = versionsPage;
let timer = null;
let followed = null;           // {job, label}: the job the message at the top follows
let offlineSince = null;
let busyAtOutage = [];         // the jobs queued or running when the service stopped answering
let initTouched = false;

const $ = (id) => document.getElementById(id);

// -- token ----------------------------------------------------------------------------------------------------
function token() { return sessionStorage.getItem(TOKEN_KEY); }

function showToken() {
  const has = Boolean(token());
  $("token-form").hidden = !tokenRequired || has;
  $("token-set").hidden = !tokenRequired || !has;
  for (const b of document.querySelectorAll("[data-needs-token]")) {
    b.classList.toggle("locked", tokenRequired && !has);
  }
}

// -- the message at the top -----------------------------------------------------------------------------------
function show(text, tone, button) {  // button: an element after the text (a job's "Run again")
  const box = $("message");
  box.textContent = text;
  if (button) box.append(" ", button);
  box.className = tone || "";
  box.hidden = !text;
}

function setFollowed(value) {
  followed = value;
  if (value) sessionStorage.setItem(FOLLOW_KEY, JSON.stringify(value));
  else sessionStorage.removeItem(FOLLOW_KEY);
}

function restoreFollowed() {
  try {
    followed = JSON.parse(sessionStorage.getItem(FOLLOW_KEY));
  } catch (err) {  // not what this page wrote: forgotten, no job followed
    console.warn("forgetting the followed job: " + err.message);
    setFollowed(null);
  }
}

function say(text, tone, button) {  // a message of its own: no job is followed any more
  setFollowed(null);
  show(text, tone, button);
}

// An interrupted job's "Run again" button, for the message (the row keeps its own).
function rerunButton(row) {
  const own = row.querySelector('button[data-action="rerun"]');
  return own ? own.cloneNode(true) : null;
}

function follow(job, label) {
  setFollowed({job: job.id, label});
  show(label + ": job " + job.id + " " + job.status + ".", "");
}

// The followed job's row (rendered by the server) says where it stands; the message repeats it.
function showFollowed() {
  if (!followed) return;
  const row = document.querySelector('.job[data-job="' + followed.job + '"]');
  if (!row) return;
  if (offlineSince !== null) {  // what the row says is what it was when the service stopped answering
    show(followed.label + ": job " + followed.job + " was " + row.dataset.status + " when the service stopped "
         + "answering; what became of it is not known until it answers again.", "warn");
  } else {
    show(followed.label + ": " + row.dataset.summary, row.dataset.tone,
         row.dataset.interrupted === "true" ? rerunButton(row) : null);
  }
}

// -- requests -------------------------------------------------------------------------------------------------
async function send(method, url, options) {
  const controller = new AbortController();
  const timeout = setTimeout(() => controller.abort(), REQUEST_TIMEOUT_MS);
  try {
    return await fetch(url, {method, ...options, signal: controller.signal});
  } catch (err) {
    throw new Error(err.name === "AbortError" ? "no answer within " + REQUEST_TIMEOUT_MS / 1000 + " s" : err.message);
  } finally {
    clearTimeout(timeout);
  }
}

function detailText(detail) {  // a 422's list of errors as "where: why; ..."
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) {
    return detail.map((e) => (e.loc || []).filter((l) => l !== "body").join(".") + ": " + e.msg).join("; ");
  }
  return JSON.stringify(detail);
}

async function call(method, url, body) {
  if (tokenRequired && !token()) {
    say("This service needs its API token: enter it above.", "bad");
    $("token-input").focus();
    return null;
  }
  const headers = {"Accept": "application/json"};
  if (body !== undefined) headers["Content-Type"] = "application/json";
  if (token()) headers["Authorization"] = "Bearer " + token();
  let response;
  try {
    response = await send(method, url, {headers, body: body === undefined ? undefined : JSON.stringify(body)});
  } catch (err) {
    setOffline(err.message);
    return null;
  }
  const answer = await response.json().catch(() => ({}));
  if (response.status === 401) {
    sessionStorage.removeItem(TOKEN_KEY);
    showToken();
    say("The token was refused: enter it again.", "bad");
    return null;
  }
  if (!response.ok) {
    say(response.status + ": " + detailText(answer.detail), "bad");
    return null;
  }
  refresh();
  return answer;
}

// -- number fields --------------------------------------------------------------------------------------------
// Number fields are text read here (templates/_number.html): a browser's number input reads "1,5" as 15 in an
// English locale, where the operator meant 1.5. A lone comma (no dot) is the decimal mark; anything else that is
// not a plain number, or is outside the field's range, is refused with a message naming the range and unit.
const NUMBER = /^[+-]?(\d+\.?\d*|\.\d+)(e[+-]?\d+)?$/i;

function parseNumber(text) {  // null when empty, NaN when not a number
  let t = text.trim();
  if (t === "") return null;
  if (!t.includes(".") && (t.match(/,/g) || []).length === 1) t = t.replace(",", ".");
  return NUMBER.test(t) ? Number(t) : NaN;
}

function numberProblem(input, value) {
  const d = input.dataset;
  const range = d.min + " .. " + d.max + " " + d.unit;
  if (Number.isNaN(value) && d.number === "integer") return "not a whole number (write e.g. 12); " + range;
  if (Number.isNaN(value)) return "not a number (write 1.5 or 1,5); " + range;
  if (value === null) return "";
  if (d.number === "integer" && !Number.isInteger(value)) return "a whole number of " + d.unit + ", " + range;
  if (value < Number(d.min) || value > Number(d.max)) return "must be within " + range + ", got " + value;
  return "";
}

function checkNumber(input) {  // the field's value (null: empty), its problem set as its validity
  const value = parseNumber(input.value);
  const problem = numberProblem(input, value);
  input.setCustomValidity(problem ? input.dataset.what + ": " + problem : "");
  return problem ? NaN : value;
}

const DATASET_ID = /^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$/;

function checkDatasetId(input) {  // the browser alone says only "Please match the requested format."
  const bad = input.value !== "" && !DATASET_ID.test(input.value);
  input.setCustomValidity(bad ? "dataset id: " + input.title : "");
}

// A form's fields checked; false (the first problem shown beside its field and at the top) when one is refused.
// ``reveal``: what makes the fields visible first (the options' fold).
function formValid(form, reveal) {
  for (const input of form.querySelectorAll("[data-number]")) checkNumber(input);
  for (const input of form.querySelectorAll('input[name="dataset"]')) checkDatasetId(input);
  if (form.checkValidity()) return true;
  if (reveal) reveal();
  say(form.querySelector("input:invalid, select:invalid").validationMessage, "bad");  // (a fieldset matches too)
  form.reportValidity();
  return false;
}

document.addEventListener("input", (event) => {
  if (event.target.matches("[data-number]")) checkNumber(event.target);
  if (event.target.matches('#capture-form input[name="dataset"]')) checkDatasetId(event.target);
});

// -- calibration options --------------------------------------------------------------------------------------
function numberField(fields, name) { return checkNumber(fields.namedItem(name)); }

// A field the form needs filled: marked invalid (the browser and the page point at it), its reason thrown.
class MissingField extends Error {
  constructor(input, why) {
    super(input.dataset.what + ": " + why);
    input.setCustomValidity(this.message);
    this.input = input;
  }
}

// [values, sigma] of a prior's group, null when all empty; the first empty field marked when only some are given.
function priorGroup(fields, names, sigmaName, what) {
  const values = names.map((n) => numberField(fields, n));
  const sigma = numberField(fields, sigmaName);
  if (values.every((v) => v === null) && sigma === null) return null;
  const empty = names.find((n, k) => values[k] === null);
  if (empty) throw new MissingField(fields.namedItem(empty), "empty; " + what + " needs all three values");
  if (sigma === null) {
    throw new MissingField(fields.namedItem(sigmaName), "empty; give how well the drawing knows " + what
                           + " (e.g. " + (sigmaName === "prior-sigma-cm" ? "1 cm" : "2°") + "), or empty all four");
  }
  return [values, sigma];
}

function calibrationBody(dataset) {
  const fields = $("calibrate-form").elements;
  const body = {dataset, init: startFor(datasetRow(dataset)).init,
                auto_activate: fields.namedItem("auto_activate").checked};
  if (fields.namedItem("method").value) body.method = fields.namedItem("method").value;
  const lever = priorGroup(fields, ["prior-x", "prior-y", "prior-z"], "prior-sigma-cm", "the lever arm");
  const angles = priorGroup(fields, ["prior-roll", "prior-pitch", "prior-yaw"], "prior-sigma-deg", "the mounting angles");
  if (lever || angles) {
    body.prior = {};
    // The page gives a lever arm in cm, as its tables show it; the API takes metres (xyz_m).
    if (lever) Object.assign(body.prior, {xyz_m: lever[0].map((cm) => cm / 100), sigma_cm: lever[1]});
    if (angles) Object.assign(body.prior, {rpy_deg: angles[0], sigma_deg: angles[1]});
  }
  if (fields.namedItem("fix-translation").checked) body.fix_translation = true;
  const rotation = numberField(fields, "tolerance-deg");
  const translation = numberField(fields, "tolerance-cm");
  if (rotation !== null || translation !== null) {
    body.tolerance = {};
    if (rotation !== null) body.tolerance.rotation_deg = rotation;
    if (translation !== null) body.tolerance.translation_cm = translation;
  }
  return body;
}

// -- where each dataset's calibration starts -------------------------------------------------------------------
// The active version starts only datasets of its rig (camera model and size, LiDAR): the server renders which
// fit (data-fits-active); the others start from their rig file's guess, and the page says so in their row.
function datasetRow(id) {
  return [...document.querySelectorAll("[data-part=datasets] .row")].find((r) => r.dataset.dataset === id) || null;
}

function activeNumber() { return document.querySelector("[data-part=summary] .summary").dataset.active; }

function startFor(row) {  // {init, note}: what "Calibrate" on this dataset's row sends, in words
  const choice = $("init-select").value;
  const guess = !row || row.dataset.guess === "true";
  const fromGuess = guess ? "its rig file's guess" : "a global search (its rig file has no guess)";
  if (choice === "search") return {init: "search", note: "a global search"};
  if (choice === "rig") return {init: "rig", note: fromGuess};
  if (row && row.dataset.fitsActive !== "true") {
    return {init: "rig", note: fromGuess + ", not the active version: " + row.dataset.otherRig};
  }
  return {init: "active", note: "version " + activeNumber() + ", the active one"};
}

const INIT_HELP = {
  active: "Datasets of the active version's rig start from it; others from their rig file's guess.",
  rig: "The dataset's rig.yaml guess, else the rig file's; without one, a global search.",
  search: "A global search over the mounts: no guess needed (after a reassembly).",
};

// The first calibration on a fresh install cannot start from an active version: the rig file's guess then.
function syncInit() {
  const active = activeNumber();
  const select = $("init-select");
  select.querySelector('option[value="active"]').disabled = !active;
  $("first-activation").hidden = Boolean(active);
  if (!active && select.value === "active") select.value = "rig";
  if (active && !initTouched && select.value === "rig") select.value = "active";
  $("init-help").textContent = INIT_HELP[select.value];
  for (const row of document.querySelectorAll("[data-part=datasets] .row")) {
    const note = row.querySelector(".start-note");
    if (note) note.textContent = "Calibrate starts from " + startFor(row).note;
  }
}

// -- activation -----------------------------------------------------------------------------------------------
// Anything but a trusted version is activated only after the operator has read how far it moves the rig's
// extrinsics, which axes it does not know, and why it is not trusted.
function confirmActivation(row) {
  const number = row.dataset.version;
  const verdict = row.dataset.verdict;
  const active = activeNumber();
  $("confirm-title").textContent = "Activate version " + number + "?";
  $("confirm-move").textContent = row.dataset.move
    ? "It moves the rig's extrinsics by " + row.dataset.move + "."
    : active ? "Version " + active + " is of another rig: the two are not compared."
      : "Nothing is active: it becomes the rig's first extrinsics.";
  $("confirm-unknown").textContent = verdict === "none" ? "Nothing measured how well any axis is known."
    : row.dataset.unknown ? "Not known to the tolerance: " + row.dataset.unknown + "." : "";
  $("confirm-lead").textContent = verdict === "none" ? "It has no verdict:" : "Its verdict is " + verdict + ":";
  $("confirm-reasons").replaceChildren(...[...row.querySelectorAll(".reasons li")].map((li) => {
    const item = document.createElement("li");
    item.textContent = li.textContent;
    return item;
  }));
  $("confirm-yes").textContent = "Activate version " + number + " anyway";
  $("confirm-no").textContent = active ? "Keep version " + active : "Do not activate";
  const dialog = $("confirm");
  return new Promise((resolve) => {
    const done = (answer) => () => { dialog.close(); resolve(answer); };
    $("confirm-yes").onclick = done(true);
    $("confirm-no").onclick = done(false);
    dialog.oncancel = () => resolve(false);  // Esc
    dialog.showModal();
  });
}

function activatedText(v) {  // the version just activated, with what its verdict does not vouch for
  if (!v.verdict) return "Version " + v.number + " is " + v.status + ". It has no verdict: nothing measured it.";
  const weak = v.verdict.weak_axes || [];
  return "Version " + v.number + " is " + v.status + ", verdict " + v.verdict.status
    + (weak.length ? ": " + weak.join(", ") + " not known to the tolerance." : ".");
}

// -- captures ---------------------------------------------------------------------------------------------------
function datasetPairs(id) {  // the pairs a listed dataset holds (0: not listed, a new one)
  const row = [...document.querySelectorAll("[data-part=datasets] .row")].find((r) => r.dataset.dataset === id);
  return row ? Number(row.dataset.pairs) : 0;
}

// "pairs" is the count the dataset should hold in all: a capture into one that holds as many would write nothing.
function nothingToCapture(id, n) {
  const held = id ? datasetPairs(id) : 0;
  if (!held || n === null || n > held) return null;  // (empty: the rig file's count, which the service knows)
  return "Dataset " + id + " holds " + held + " pairs already: a capture to " + n + " pairs in all would "
    + "write none. Set \"pairs in all\" above " + held + " to add pairs.";
}

// -- the advice's actions -------------------------------------------------------------------------------------
function openOptions(focusName) {
  $("calibrate-options").open = true;
  const field = $("calibrate-form").elements.namedItem(focusName);
  field.scrollIntoView({block: "center"});
  field.focus();
}

function markDataset(id) {
  for (const row of document.querySelectorAll("[data-part=datasets] .row")) {
    row.classList.toggle("marked", row.dataset.dataset === id);
  }
}

const advice = {
  prior(id, el) {
    const given = el.dataset.lever ? el.dataset.lever.split(",") : null;
    if (given) {  // the lever arm that calibration was given, back in the fields: compare it with the drawing
      const form = $("calibrate-form").elements;
      ["prior-x", "prior-y", "prior-z"].forEach((name, k) => { form.namedItem(name).value = given[k]; });
    }
    openOptions("prior-x");
    say(given ? "The lever arm that calibration was given, in cm: " + given.join(", ") + ". Check it against the "
                + "rig's drawing (cm, not m), then Calibrate " + id + "."
              : "Type the lever arm from the rig's drawing in cm (and how well it knows it), then Calibrate " + id
                + ".", "");
  },
  fix(id) {
    $("calibrate-form").elements.namedItem("fix-translation").checked = true;
    openOptions("fix-translation");
    say("The translation will be held at the lever arm given (else the start's): Calibrate " + id + ".", "");
  },
  search(id) {
    $("init-select").value = "search";
    initTouched = true;
    $("init-select").scrollIntoView({block: "center"});
    say("The next calibration starts from a global search: Calibrate " + id + ".", "");
  },
  capture(id, el) {
    const form = $("capture-form").elements;
    form.namedItem("dataset").value = id;
    const n = form.namedItem("n");
    if (el.dataset.pairs) n.value = el.dataset.pairs;  // the advice's one target, in all
    checkNumber(n);
    n.focus();
    $("capture").scrollIntoView({block: "center"});
    say("A capture into " + id + " continues it at its next pair, up to " + (n.value || "the pairs set") + " in all"
        + " (it holds " + datasetPairs(id) + " now).", "");
  },
};

// -- a lever arm in the wrong unit ----------------------------------------------------------------------------
// A lever arm in metres typed into the cm fields reaches rigd 100 times too short, one in mm 10 times too long:
// both are asked about before anything is sent.
const LEVER_SMALL_CM = 1;  // every axis below this: no camera and LiDAR sit that close (metres typed?)
const LEVER_LARGE_CM = 200;  // farther apart than this: millimetres typed? (a car's roof to its windscreen)

function leverDoubt(cm) {  // null, or {said, fixed}: what the lever arm would mean in the other unit
  const far = Math.hypot(...cm);
  const show = (v) => v.map((x) => +x.toFixed(2)).join(", ");
  if (cm.every((x) => Math.abs(x) < LEVER_SMALL_CM)) {
    const fixed = cm.map((x) => x * 100);
    return {fixed, said: "The lever arm " + show(cm) + " cm puts the LiDAR " + far.toFixed(2) + " cm from the "
            + "camera. Were these metres? In cm they are " + show(fixed) + "."};
  }
  if (far > LEVER_LARGE_CM) {
    const fixed = cm.map((x) => x / 10);
    return {fixed, said: "The lever arm " + show(cm) + " cm puts the LiDAR " + (far / 100).toFixed(2) + " m from "
            + "the camera. Were these millimetres? In cm they are " + show(fixed) + "."};
  }
  return null;
}

function askLever(doubt) {  // "fix" | "keep" | "back"
  $("lever-said").textContent = doubt.said;
  $("lever-fix").textContent = "Use " + doubt.fixed.map((x) => +x.toFixed(2)).join(", ") + " cm";
  const dialog = $("lever-check");
  return new Promise((resolve) => {
    const done = (answer) => () => { dialog.close(); resolve(answer); };
    $("lever-fix").onclick = done("fix");
    $("lever-keep").onclick = done("keep");
    $("lever-back").onclick = done("back");
    dialog.oncancel = () => resolve("back");  // Esc
    dialog.showModal();
  });
}

// The body with the lever arm as the operator confirmed it; null when they went back to change it.
async function checkedLever(body) {
  const xyz = body.prior && body.prior.xyz_m;
  const doubt = xyz ? leverDoubt(xyz.map((m) => m * 100)) : null;
  if (!doubt) return body;
  const answer = await askLever(doubt);
  if (answer === "back") { openOptions("prior-x"); say("Nothing was sent: correct the lever arm (cm).", ""); return null; }
  if (answer === "fix") {
    const form = $("calibrate-form").elements;
    ["prior-x", "prior-y", "prior-z"].forEach((name, k) => { form.namedItem(name).value = +doubt.fixed[k].toFixed(4); });
    body.prior.xyz_m = doubt.fixed.map((cm) => cm / 100);
  }
  return body;
}

// -- buttons --------------------------------------------------------------------------------------------------
const actions = {
  async calibrate(el) {
    const form = $("calibrate-form");
    if (!formValid(form, () => { $("calibrate-options").open = true; })) return;
    let body;
    try {
      body = calibrationBody(el.dataset.dataset);
    } catch (err) {
      $("calibrate-options").open = true;
      say(err.message, "bad");
      if (err instanceof MissingField) { err.input.focus(); form.reportValidity(); }
      return;
    }
    const start = startFor(datasetRow(body.dataset)).note;
    body = await checkedLever(body);
    if (!body) return;
    const job = await call("POST", "/calibrate", body);
    if (job) follow(job, "Calibration of " + body.dataset + " from " + start);
  },
  async check(el) {
    const job = await call("POST", "/check", {dataset: el.dataset.dataset, against: "active"});
    if (job) follow(job, "Check");
  },
  async activate(el) {
    const row = el.closest(".version");
    if (row.dataset.verdict !== "trusted" && !(await confirmActivation(row))) {
      say("Version " + el.dataset.version + " was not activated.", "");
      return;
    }
    const v = await call("POST", "/extrinsics/versions/" + el.dataset.version + "/activate");
    if (v) say(activatedText(v), v.verdict && v.verdict.status === "trusted" ? "ok" : "warn");
  },
  async rerun(el) {
    const job = await call("POST", el.dataset.url, JSON.parse(el.dataset.body));
    if (job) follow(job, el.dataset.label || "Run again of job " + el.dataset.job);
  },
  async cancel(el) {
    const job = await call("DELETE", "/jobs/" + el.dataset.job);
    if (job) follow(job, "Cancel requested");
  },
  "more-versions"() {
    shownVersions += versionsPage;
    refresh();
  },
  advice(el) {
    markDataset(el.dataset.dataset);
    advice[el.dataset.advice](el.dataset.dataset, el);
  },
  view(el) {
    pickVersion(Number(el.dataset.version));
    $("viewer").scrollIntoView({behavior: "smooth"});
  },
  pairs(el) {
    pickDataset(el.dataset.dataset);
    $("viewer").scrollIntoView({behavior: "smooth"});
  },
  pair(el) { viewer.pair = Number(el.dataset.pair); showViewer(); },
  sensor(el) { viewer.sensor = el.dataset.sensor; showViewer(); },
  stage(el) { setStage(el.dataset.stage); },
  zoom(el) { zoomButton(el.dataset.zoom); },
  "forget-token"() {
    sessionStorage.removeItem(TOKEN_KEY);
    showToken();
  },
};

document.addEventListener("click", (event) => {
  const el = event.target.closest("[data-action]");
  if (!el || el.disabled) return;
  event.preventDefault();
  actions[el.dataset.action](el);
});

$("capture-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  if (!formValid(event.target)) return;
  const fields = event.target.elements;  // (form.dataset would be the form's data-* attributes)
  const body = {source: fields.namedItem("source").value};
  if (fields.namedItem("dataset").value) body.dataset = fields.namedItem("dataset").value;
  const n = checkNumber(fields.namedItem("n"));
  if (n !== null) body.n = n;
  const nothing = nothingToCapture(body.dataset, n);
  if (nothing) { say(nothing, "bad"); fields.namedItem("n").focus(); return; }
  const job = await call("POST", "/capture", body);
  if (job) follow(job, "Capture into " + job.params.dataset);
});

$("token-form").addEventListener("submit", (event) => {
  event.preventDefault();
  const input = $("token-input");
  sessionStorage.setItem(TOKEN_KEY, input.value);
  input.value = "";
  showToken();
  say("");
});

$("init-select").addEventListener("change", () => { initTouched = true; syncInit(); });

// -- the viewer: what it shows --------------------------------------------------------------------------------
// kind "version": a calibration's overlays (before | after, close-up, cloud); kind "dataset": captured pairs.
const viewer = {kind: null, id: null, pairs: [], sensors: [], meta: {}, pair: null, sensor: null, chosen: false,
                stage: "after"};

function csv(text) { return text ? text.split(",") : []; }

function versionSource(number) {
  const row = document.getElementById("v" + number);
  const fallback = $("viewer-default");
  const el = row && row.dataset.pairs ? row : fallback && Number(fallback.dataset.version) === number ? fallback : null;
  return el ? {pairs: csv(el.dataset.pairs).map(Number), sensors: csv(el.dataset.sensors)} : null;
}

function pickVersion(number) {
  const source = versionSource(number);
  if (!source) return;
  Object.assign(viewer, {kind: "version", id: number, ...source, meta: {}, pair: null, chosen: true});
  showViewer();
}

async function pickDataset(id) {
  let response;
  try {
    response = await send("GET", "/datasets/" + encodeURIComponent(id), {headers: {"Accept": "application/json"}});
  } catch (err) {
    setOffline(err.message);
    return;
  }
  const detail = await response.json().catch(() => ({}));
  if (!response.ok) { say(response.status + ": " + detailText(detail.detail), "bad"); return; }
  const meta = Object.fromEntries(detail.pairs.map((p) => [p.number, p.meta]));
  Object.assign(viewer, {kind: "dataset", id, pairs: detail.pairs.map((p) => p.number), sensors: detail.sensors,
                         meta, pair: null, chosen: true});
  showViewer();
}

// Until the operator picks something, the viewer follows the newest calibration.
function followNewest() {
  if (viewer.chosen) return;
  const fallback = $("viewer-default");
  const number = fallback ? Number(fallback.dataset.version) : null;
  if (number === viewer.id && viewer.kind === "version") return;
  Object.assign(viewer, number ? {kind: "version", id: number, ...versionSource(number)} : {kind: null, id: null});
}

// Overlays as JPEG: a third of a PNG's bytes (a 1920 px pinhole's was 0.8 MB), the dots as distinct.
function overlayUrl(stage) {
  const base = "/extrinsics/versions/" + viewer.id + "/overlays/" + viewer.pair + ".png?format=jpeg&stage=" + stage;
  return viewer.sensor && stage !== "cloud" ? base + "&sensor=" + encodeURIComponent(viewer.sensor) : base;
}

function pairUrl(what) {  // what: "image" or "cloud.png"
  const base = "/datasets/" + encodeURIComponent(viewer.id) + "/pairs/" + viewer.pair + "/" + what;
  return viewer.sensor && what === "image" ? base + "?sensor=" + encodeURIComponent(viewer.sensor) : base;
}

// A copy ``width`` px wide; a captured image's as JPEG (its overlays ask for JPEG already).
function withWidth(url, width) {
  const jpeg = url.includes("/image") && !url.includes("format=") ? "&format=jpeg" : "";
  return url + (url.includes("?") ? "&" : "?") + "width=" + width + jpeg;
}

// A smaller copy as wide as the screen uses (a phone need not fetch a 2048 px panorama for 360 px).
function shownWidth(el) {
  const wanted = Math.max(el.clientWidth, 320) * (window.devicePixelRatio || 1);
  return Math.min(4096, Math.ceil(wanted / 256) * 256);
}

function chip(action, value, label, current) {
  const b = document.createElement("button");
  b.type = "button";
  b.className = "plain";
  b.dataset.action = action;
  b.dataset[action] = value;
  b.textContent = label;
  b.classList.toggle("current", current);
  b.setAttribute("aria-pressed", String(current));
  return b;
}

function showChoices() {
  if (!viewer.pairs.includes(viewer.pair)) viewer.pair = viewer.pairs.length ? viewer.pairs[0] : null;
  if (!viewer.sensors.includes(viewer.sensor)) viewer.sensor = viewer.sensors.length ? viewer.sensors[0] : null;
  $("viewer-pairs").replaceChildren(...viewer.pairs.map((p) => chip("pair", p, "pair " + p, p === viewer.pair)));
  const label = document.createElement("span");
  label.className = "muted";
  label.textContent = "sensor";
  $("viewer-sensors").hidden = viewer.sensors.length === 0;
  $("viewer-sensors").replaceChildren(...(viewer.sensors.length ? [label] : []),
                                      ...viewer.sensors.map((s) => chip("sensor", s, s, s === viewer.sensor)));
}

// A captured pair's meta.yaml in the page's units (° and cm; ms between clocks): what the capture measured of it.
function pairMetaText(meta) {
  const m = meta || {};
  const motion = m.motion || {};
  const lidar = m.lidar || {};
  const num = (v) => typeof v === "number" && Number.isFinite(v);
  const parts = [];
  if (m.source) parts.push(String(m.source));
  if (m.scene) parts.push(m.scene + " scene" + (num(m.seed) ? " (seed " + m.seed + ")" : ""));
  if (num(m.range_noise_m)) parts.push("range noise " + +(m.range_noise_m * 100).toFixed(2) + " cm");
  if (num(m.camera_minus_lidar_s)) parts.push("camera − LiDAR time " + Math.round(m.camera_minus_lidar_s * 1000) + " ms");
  if (num(motion.still_seconds)) parts.push("held still " + +motion.still_seconds.toFixed(1) + " s");
  if (num(motion.lidar_rotation_deg) && num(motion.lidar_translation_m)) {
    parts.push("LiDAR moved " + motion.lidar_rotation_deg.toFixed(3) + "° and "
               + (motion.lidar_translation_m * 100).toFixed(2) + " cm while still"
               + (num(motion.lidar_still_rotation_deg) && num(motion.lidar_still_translation_m)
                 ? " (within " + motion.lidar_still_rotation_deg.toFixed(3) + "° and "
                   + (motion.lidar_still_translation_m * 100).toFixed(2) + " cm)" : ""));
  }
  if (num(motion.moved_since_previous_m)) parts.push("moved " + Math.round(motion.moved_since_previous_m * 100) + " cm since the previous pair");
  if (num(lidar.points)) parts.push(lidar.points.toLocaleString("en") + " points" + (num(lidar.sweeps_fused) ? " from " + lidar.sweeps_fused + " sweeps" : ""));
  if (num(lidar.packets_lost) && lidar.packets_lost) parts.push(lidar.packets_lost + " packets lost");
  return parts.join(" · ");
}

function showViewer() {
  followNewest();
  const on = viewer.kind !== null;
  $("viewer-empty").hidden = on;
  $("viewer-body").hidden = !on;
  if (!on) { $("viewer-title").textContent = ""; return; }
  showChoices();
  const version = viewer.kind === "version";
  $("viewer-title").textContent = (version ? "version " + viewer.id : "dataset " + viewer.id + " as captured")
    + ", pair " + viewer.pair + (viewer.sensor ? ", " + viewer.sensor : "");
  $("stage-toggle").hidden = !version;
  $("lens-help").hidden = !version;  // a captured pair has no dots and no before | after
  $("lens-help-pair").hidden = version;
  $("closeup").hidden = !version;
  $("pair-meta").hidden = version;
  $("pair-meta").textContent = version ? "" : pairMetaText(viewer.meta[viewer.pair]);
  $("cloud-caption").textContent = version
    ? "the whole cloud from above (forward is up), each point in the colour of the pixel it lands on with this "
      + "version: with wrong extrinsics, walls and cars bleed onto the ground beside them."
    : "the cloud from above (forward is up), coloured from the image with the rig file's initial guess (grey "
      + "without one)";
  const figures = {closeup: version ? overlayUrl("closeup") : null, cloud: version ? overlayUrl("cloud") : pairUrl("cloud.png")};
  for (const [name, url] of Object.entries(figures)) {
    const img = $("ov-" + name);
    if (!url) continue;
    const src = withWidth(url, shownWidth(img.closest("figure")));
    if (img.getAttribute("src") !== src) img.src = src;
  }
  setLens(version ? {before: overlayUrl("before"), after: overlayUrl("after")} : {after: pairUrl("image")});
}

// -- the viewer: zoom, pan, before | after --------------------------------------------------------------------
// The images fill the lens at zoom 1 ("fit"); zoom z shows them z times larger, panned by (tx, ty) CSS px.
// A copy as wide as the lens is loaded first; zooming past it loads the file at full resolution.
const lens = {urls: {}, z: 1, tx: 0, ty: 0, full: false, natural: null, pointers: new Map(), gesture: null};
const MAX_ZOOM = 16;

function lensImages() { return {before: $("lens-before"), after: $("lens-after")}; }

function setLens(urls) {
  if (JSON.stringify(urls) === JSON.stringify(lens.urls)) return;
  Object.assign(lens, {urls, z: 1, tx: 0, ty: 0, full: false, natural: null});
  if (!urls.before) viewer.stage = "after";
  loadLens();
  setStage(viewer.stage);
}

function loadLens() {
  const el = $("lens");
  for (const [stage, img] of Object.entries(lensImages())) {
    const url = lens.urls[stage];
    if (!url) { img.removeAttribute("src"); continue; }
    const src = lens.full ? url : withWidth(url, shownWidth(el));
    if (img.getAttribute("src") !== src) img.src = src;
  }
  el.dataset.full = String(lens.full);
}

function setStage(stage) {
  viewer.stage = stage;
  const images = lensImages();
  images.before.hidden = stage !== "before" || !lens.urls.before;
  images.after.hidden = stage === "before" && Boolean(lens.urls.before);
  $("lens").dataset.stage = stage;
  for (const b of document.querySelectorAll("#stage-toggle button")) {
    const current = b.dataset.stage === stage;
    b.classList.toggle("current", current);
    b.setAttribute("aria-pressed", String(current));
  }
}

function lensShownImage() {
  const images = lensImages();
  return images.before.hidden ? images.after : images.before;
}

// The lens takes the image's shape, no taller than most of the screen.
function fitLens(img) {
  if (!img.naturalWidth) return;
  const el = $("lens");
  const aspect = img.naturalWidth / img.naturalHeight;
  el.style.aspectRatio = String(aspect);
  el.style.maxWidth = Math.round(window.innerHeight * 0.75 * aspect) + "px";
  const asked = /[?&]width=(\d+)/.exec(img.getAttribute("src"));
  if (!asked || img.naturalWidth < Number(asked[1])) {  // the file itself, not a smaller copy
    lens.natural = {w: img.naturalWidth, h: img.naturalHeight};
    lens.full = true;
    el.dataset.full = "true";
  }
  applyLens();
}

function clampPan() {
  const el = $("lens");
  const w = el.clientWidth;
  const h = el.clientHeight;
  lens.tx = Math.min(0, Math.max(w - w * lens.z, lens.tx));
  lens.ty = Math.min(0, Math.max(h - h * lens.z, lens.ty));
}

function applyLens() {
  clampPan();
  const el = $("lens");
  const transform = "translate(" + lens.tx + "px, " + lens.ty + "px) scale(" + lens.z + ")";
  const beyond = lens.z > 1 && lens.natural && lens.z * el.clientWidth > lens.natural.w;  // zoomed past 1:1
  for (const img of Object.values(lensImages())) {
    img.style.transform = transform;
    img.style.imageRendering = beyond ? "pixelated" : "auto";
  }
  el.dataset.zoom = lens.z.toFixed(3);
  el.classList.toggle("zoomed", lens.z > 1);
  $("zoom-label").textContent = zoomText(el);
  const shown = lensShownImage();
  if (!lens.full && shown.naturalWidth && lens.z * el.clientWidth * (window.devicePixelRatio || 1) > shown.naturalWidth) {
    lens.full = true;
    loadLens();
  }
}

function zoomText(el) {
  if (!lens.natural) return lens.z === 1 ? "fit" : "×" + lens.z.toFixed(1);
  const percent = Math.round(lens.z * el.clientWidth / lens.natural.w * 100);
  return (lens.z === 1 ? "fit, " : "") + percent + " % of full resolution (" + lens.natural.w + "×" + lens.natural.h + " px)";
}

function zoomAt(z, x, y) {  // to zoom z, keeping the lens point (x, y) where it is
  const next = Math.min(MAX_ZOOM, Math.max(1, z));
  lens.tx = x - (x - lens.tx) * next / lens.z;
  lens.ty = y - (y - lens.ty) * next / lens.z;
  lens.z = next;
  applyLens();
}

async function fullSize() {
  if (!lens.full) { lens.full = true; loadLens(); }
  const img = lensShownImage();
  await img.decode().catch(() => null);
  if (img.naturalWidth) lens.natural = {w: img.naturalWidth, h: img.naturalHeight};
  return lens.natural;
}

async function zoomButton(how) {
  const el = $("lens");
  const cx = el.clientWidth / 2;
  const cy = el.clientHeight / 2;
  if (how === "fit") { lens.z = 1; lens.tx = 0; lens.ty = 0; applyLens(); return; }
  if (how === "in" || how === "out") { zoomAt(lens.z * (how === "in" ? 1.5 : 1 / 1.5), cx, cy); return; }
  const natural = await fullSize();  // "full": one image pixel per CSS pixel
  if (natural) zoomAt(natural.w / el.clientWidth, cx, cy);
}

function lensPoint(event) {
  const box = $("lens").getBoundingClientRect();
  return {x: event.clientX - box.left, y: event.clientY - box.top};
}

function startGesture() {
  const points = [...lens.pointers.values()];
  if (points.length === 1) {
    lens.gesture = {kind: "pan", x: points[0].x, y: points[0].y, tx: lens.tx, ty: lens.ty};
  } else if (points.length === 2) {
    const [a, b] = points;
    lens.gesture = {kind: "pinch", d: Math.hypot(a.x - b.x, a.y - b.y) || 1, z: lens.z};
  }
}

function moveGesture() {
  const points = [...lens.pointers.values()];
  const g = lens.gesture;
  if (!g) return;
  if (g.kind === "pan" && points.length === 1) {
    lens.tx = g.tx + points[0].x - g.x;
    lens.ty = g.ty + points[0].y - g.y;
    applyLens();
  } else if (g.kind === "pinch" && points.length === 2) {
    const [a, b] = points;
    zoomAt(g.z * Math.hypot(a.x - b.x, a.y - b.y) / g.d, (a.x + b.x) / 2, (a.y + b.y) / 2);
  }
}

function lensEvents() {
  const el = $("lens");
  el.addEventListener("pointerdown", (e) => {
    el.setPointerCapture(e.pointerId);
    lens.pointers.set(e.pointerId, lensPoint(e));
    startGesture();
  });
  el.addEventListener("pointermove", (e) => {
    if (!lens.pointers.has(e.pointerId)) return;
    lens.pointers.set(e.pointerId, lensPoint(e));
    moveGesture();
  });
  for (const type of ["pointerup", "pointercancel"]) {
    el.addEventListener(type, (e) => { lens.pointers.delete(e.pointerId); startGesture(); });
  }
  el.addEventListener("wheel", (e) => {
    e.preventDefault();
    const p = lensPoint(e);
    zoomAt(lens.z * Math.exp(-e.deltaY * 0.002), p.x, p.y);
  }, {passive: false});
  el.addEventListener("dblclick", (e) => { const p = lensPoint(e); zoomAt(lens.z * (e.shiftKey ? 0.5 : 2), p.x, p.y); });
  for (const img of Object.values(lensImages())) img.addEventListener("load", () => fitLens(img));
  document.addEventListener("keydown", (e) => {
    const typing = e.target.closest && e.target.closest("input, select, textarea");
    if (e.key.toLowerCase() !== "b" || typing || $("viewer-body").hidden || !lens.urls.before) return;
    setStage(viewer.stage === "before" ? "after" : "before");
  });
  window.addEventListener("resize", () => applyLens());
}

// -- refresh and the unreachable-service banner ---------------------------------------------------------------
function setOffline(reason) {
  if (reason === null) {
    offlineSince = null;
  } else if (offlineSince === null) {
    offlineSince = new Date();
    busyAtOutage = [...document.querySelectorAll('.job[data-status="queued"], .job[data-status="running"]')]
      .map((row) => row.dataset.job);
    showFollowed();
  }
  document.body.classList.toggle("offline", offlineSince !== null);
  $("offline").hidden = offlineSince === null;
  if (offlineSince !== null) {
    $("offline-why").textContent = "Since " + offlineSince.toLocaleTimeString() + " (" + reason + "). The page "
      + "shows what it last knew; it keeps asking every few seconds. Is rigd serve running and this computer on "
      + "the rig's network?";
  }
}

function liveUrl() {
  const have = Object.entries(hashes).map(([name, hash]) => name + ":" + hash).join(",");
  return "/ui/live?shown=" + shownVersions + "&have=" + encodeURIComponent(have);
}

function swapParts(live) {
  for (const [name, html] of Object.entries(live.parts)) {
    document.querySelector('[data-part="' + name + '"]').innerHTML = html;
  }
  Object.assign(hashes, live.hashes);
}

async function refresh() {
  clearTimeout(timer);
  let busy = false;
  try {
    const response = await send("GET", liveUrl(), {headers: {"Accept": "application/json"}});
    const live = await response.json().catch(() => ({}));
    if (response.status >= 500) throw new Error(response.status + ": " + detailText(live.detail));
    if (!response.ok) throw new Error("GET /ui/live: " + response.status + " " + detailText(live.detail));
    busy = live.busy;
    const back = offlineSince !== null;
    setOffline(null);
    swapParts(live);
    afterParts();
    if (back) afterOutage();
  } catch (err) {
    setOffline(err.message);
  }
  // A tab in the background (a phone in a pocket) asks rarely, and at once when it is looked at again.
  timer = setTimeout(refresh, document.hidden ? 30000 : offlineSince !== null ? 3000 : busy ? 1000 : 4000);
}

// The service answers again: say what became of the jobs that were running (a restart interrupts them), and load
// again the images that failed while it did not answer (they would stay broken, on a phone too).
function afterOutage() {
  reloadFailedImages();
  const interrupted = busyAtOutage.map((id) => document.querySelector('.job[data-job="' + id + '"]'))
    .filter((row) => row && row.dataset.interrupted === "true");
  busyAtOutage = [];
  const mine = followed && interrupted.find((row) => row.dataset.job === String(followed.job));
  if (mine) return;  // the followed job's message says so, with its button (showFollowed)
  if (interrupted.length) {
    const row = interrupted[0];
    const more = interrupted.length > 1 ? " (and " + (interrupted.length - 1) + " more, see Jobs)" : "";
    say("The service answers again, after a restart: " + row.dataset.summary + more + ".", "bad", rerunButton(row));
  } else if (!followed || !document.querySelector('.job[data-job="' + followed.job + '"]')) {
    say("The service answers again.", "ok");
  }
}

function reloadFailedImages() {
  for (const img of document.querySelectorAll("#viewer img[src]")) {
    if (img.complete && img.naturalWidth === 0) {
      const src = img.getAttribute("src");
      img.removeAttribute("src");
      img.setAttribute("src", src);
    }
  }
}

// Times are rendered in UTC (the server does not know the browser's zone): shown in local time, as the banner's.
function localTimes() {
  for (const el of document.querySelectorAll("time[data-local]")) {
    const when = new Date(el.getAttribute("datetime"));
    if (Number.isNaN(when.getTime())) continue;
    el.textContent = el.dataset.local === "date" ? when.toLocaleString() : when.toLocaleTimeString();
    el.title = el.getAttribute("datetime");
  }
}

function afterParts() {
  localTimes();
  showToken();
  syncInit();
  showFollowed();
  showViewer();
}

document.addEventListener("visibilitychange", () => { if (!document.hidden) refresh(); });

for (const part of document.querySelectorAll("[data-part]")) hashes[part.dataset.part] = part.dataset.hash;
lensEvents();
restoreFollowed();
afterParts();
timer = setTimeout(refresh, 1000);
