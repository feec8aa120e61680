// rigd operator page: refreshes the server-rendered parts from GET /ui/live and sends the buttons' requests
// to the JSON API with fetch(). The bearer token (when the service has one) lives in this tab's sessionStorage.
"use strict";

const TOKEN_KEY = "rigd-token";
const tokenRequired = document.body.dataset.tokenRequired === "true";
const shown = {};              // part name -> the HTML last put into it
let viewer = {version: null, pair: null, sensor: null, chosen: false};
let timer = null;

function token() { return sessionStorage.getItem(TOKEN_KEY); }

function showToken() {
  const has = Boolean(token());
  document.getElementById("token-form").hidden = !tokenRequired || has;
  document.getElementById("token-set").hidden = !tokenRequired || !has;
  for (const b of document.querySelectorAll("[data-needs-token]")) {
    b.classList.toggle("locked", tokenRequired && !has);
  }
}

function say(text, isError) {
  const box = document.getElementById("message");
  box.textContent = text;
  box.className = isError ? "error" : "";
  box.hidden = !text;
}

async function call(method, url, body) {
  if (tokenRequired && !token()) {
    say("This service needs its API token: enter it above.", true);
    document.getElementById("token-input").focus();
    return null;
  }
  const headers = {"Accept": "application/json"};
  if (body !== undefined) headers["Content-Type"] = "application/json";
  if (token()) headers["Authorization"] = "Bearer " + token();
  let response;
  try {
    response = await fetch(url, {method, headers, body: body === undefined ? undefined : JSON.stringify(body)});
  } catch (err) {
    say("The service did not answer: " + err.message, true);
    return null;
  }
  const answer = await response.json().catch(() => ({}));
  if (response.status === 401) {
    sessionStorage.removeItem(TOKEN_KEY);
    showToken();
    say("The token was refused: enter it again.", true);
    return null;
  }
  if (!response.ok) {
    const detail = typeof answer.detail === "string" ? answer.detail : JSON.stringify(answer.detail);
    say(response.status + ": " + detail, true);
    return null;
  }
  refresh();
  return answer;
}

const actions = {
  async calibrate(el) {
    const body = {dataset: el.dataset.dataset, init: document.getElementById("init-select").value,
                  auto_activate: document.getElementById("auto-activate").checked};
    const job = await call("POST", "/calibrate", body);
    if (job) say("Calibration of " + body.dataset + ": job " + job.id + " " + job.status + ".");
  },
  async check(el) {
    const job = await call("POST", "/check", {dataset: el.dataset.dataset, against: "active"});
    if (job) say("Check of the active version on " + el.dataset.dataset + ": job " + job.id + " " + job.status + ".");
  },
  async activate(el) {
    const v = await call("POST", "/extrinsics/versions/" + el.dataset.version + "/activate");
    if (v) say("Version " + v.number + " is " + v.status + ".");
  },
  async cancel(el) {
    const job = await call("DELETE", "/jobs/" + el.dataset.job);
    if (job) say("Job " + job.id + ": " + job.status + ".");
  },
  view(el) {
    viewer = {version: Number(el.dataset.version), pair: null, sensor: viewer.sensor, chosen: true};
    showOverlays();
    document.getElementById("overlays").scrollIntoView({behavior: "smooth"});
  },
  pair(el) {
    viewer.pair = Number(el.dataset.pair);
    viewer.chosen = true;
    showOverlays();
  },
  sensor(el) {
    viewer.sensor = el.dataset.sensor;
    viewer.chosen = true;
    showOverlays();
  },
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

document.getElementById("capture-form").addEventListener("submit", async (event) => {
  event.preventDefault();
  const fields = event.target.elements;  // (form.dataset would be the form's data-* attributes)
  const body = {source: fields.namedItem("source").value};
  if (fields.namedItem("dataset").value) body.dataset = fields.namedItem("dataset").value;
  if (fields.namedItem("n").value) body.n = Number(fields.namedItem("n").value);
  const job = await call("POST", "/capture", body);
  if (job) say("Capture into " + job.params.dataset + ": job " + job.id + ".");
});

document.getElementById("token-form").addEventListener("submit", (event) => {
  event.preventDefault();
  const input = document.getElementById("token-input");
  sessionStorage.setItem(TOKEN_KEY, input.value);
  input.value = "";
  showToken();
  say("");
});

// A head's overlays are per sensor, its cloud per pair; one camera's have no sensor (sensor null).
function overlayUrl(version, pair, stage, sensor) {
  const url = "/extrinsics/versions/" + version + "/overlays/" + pair + ".png?stage=" + stage;
  return sensor && stage !== "cloud" ? url + "&sensor=" + encodeURIComponent(sensor) : url;
}

function chip(action, value, label, current) {
  const b = document.createElement("button");
  b.type = "button";
  b.dataset.action = action;
  b.dataset[action] = value;
  b.textContent = label;
  b.classList.toggle("current", current);
  b.setAttribute("aria-pressed", String(current));
  return b;
}

// Shown at most as wide as the screen can use (a phone need not fetch a 2048 px panorama); the link is full size.
function shownWidth(figure) {
  const wanted = Math.max(figure.clientWidth, 320) * (window.devicePixelRatio || 1);
  return Math.min(4096, Math.ceil(wanted / 256) * 256);
}

// The viewer follows the newest version with overlays until the operator picks one.
function showOverlays() {
  const rows = [...document.querySelectorAll(".version[data-pairs]")].filter((r) => r.dataset.pairs !== "");
  if (!viewer.chosen || !rows.some((r) => Number(r.dataset.version) === viewer.version)) {
    viewer.version = rows.length ? Number(rows[0].dataset.version) : null;
    viewer.pair = null;
  }
  const row = rows.find((r) => Number(r.dataset.version) === viewer.version);
  const pairs = row ? row.dataset.pairs.split(",").map(Number) : [];
  if (!pairs.includes(viewer.pair)) viewer.pair = pairs.length ? pairs[0] : null;
  const sensors = row && row.dataset.sensors ? row.dataset.sensors.split(",") : [];  // a head's; [] for one camera
  if (!sensors.includes(viewer.sensor)) viewer.sensor = sensors.length ? sensors[0] : null;
  document.getElementById("overlay-empty").hidden = Boolean(row);
  document.getElementById("overlay-views").hidden = !row;
  document.getElementById("overlay-closeup").hidden = !row;
  document.getElementById("overlay-cloud").hidden = !row;
  document.getElementById("overlay-title").textContent = row ? "version " + viewer.version + ", pair " + viewer.pair
    + (viewer.sensor ? ", " + viewer.sensor : "") : "";
  document.getElementById("overlay-pairs").replaceChildren(...pairs.map((p) => chip("pair", p, "pair " + p, p === viewer.pair)));
  const picker = document.getElementById("overlay-sensors");
  picker.hidden = sensors.length === 0;
  const label = document.createElement("span");
  label.className = "muted";
  label.textContent = "sensor";
  picker.replaceChildren(...(sensors.length ? [label] : []),
                         ...sensors.map((s) => chip("sensor", s, s, s === viewer.sensor)));
  for (const stage of ["before", "after", "closeup", "cloud"]) {
    const img = document.getElementById("ov-" + stage);
    const link = document.getElementById("ov-" + stage + "-link");
    if (!row) { img.hidden = true; link.removeAttribute("href"); continue; }
    const url = overlayUrl(viewer.version, viewer.pair, stage, viewer.sensor);
    const src = url + "&width=" + shownWidth(img.closest("figure"));
    if (img.getAttribute("src") !== src) img.src = src;
    link.href = url;
    img.hidden = false;
  }
}

async function refresh() {
  clearTimeout(timer);
  let busy = false;
  try {
    const response = await fetch("/ui/live", {headers: {"Accept": "application/json"}});
    if (!response.ok) throw new Error("GET /ui/live: " + response.status);
    const live = await response.json();
    busy = live.busy;
    for (const [name, html] of Object.entries(live.parts)) {
      if (shown[name] === html) continue;
      document.querySelector('[data-part="' + name + '"]').innerHTML = html;
      shown[name] = html;
    }
    showToken();
    showOverlays();
  } catch (err) {
    say("Cannot refresh: " + err.message, true);
  }
  // A tab in the background (a phone in a pocket) asks rarely, and at once when it is looked at again.
  timer = setTimeout(refresh, document.hidden ? 30000 : busy ? 1000 : 4000);
}

document.addEventListener("visibilitychange", () => { if (!document.hidden) refresh(); });

showToken();
showOverlays();
timer = setTimeout(refresh, 1000);
