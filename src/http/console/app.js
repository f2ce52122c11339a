// polbrdf console (docs/console.md): queue, cache, result and submit pages
// over the service's own API. No framework, no build step, no CDN: the
// service embeds this file. Every request goes through `api()`, which adds
// the bearer token when one is entered (kept in sessionStorage only), so
// the pages work with and without --token / --token-reads; images are
// fetched the same way and shown from blob URLs.
"use strict";

const $ = (sel, root = document) => root.querySelector(sel);
const main = () => $("#main");
let token = sessionStorage.getItem("polbrdf-token") || "";
let leave = () => {}; // the current page's clean-up (event streams, timers)

function headers(extra = {}) {
  const h = Object.assign({}, extra);
  if (token) h["Authorization"] = "Bearer " + token;
  return h;
}

async function api(path, opts = {}) {
  const res = await fetch(path, Object.assign({}, opts, { headers: headers(opts.headers || {}) }));
  const type = res.headers.get("content-type") || "";
  const body = type.includes("json") ? await res.json() : await res.text();
  if (!res.ok) {
    const err = new Error(typeof body === "object" ? body.detail || body.title : String(body));
    err.problem = typeof body === "object" ? body : null;
    err.status = res.status;
    throw err;
  }
  return { body, res };
}

/** An element: el("td", {class: "num"}, "text", child, …). */
function el(tag, attrs = {}, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v === null || v === undefined || v === false) continue;
    if (k.startsWith("on")) e.addEventListener(k.slice(2), v);
    else e.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}

function announce(text) { $("#status").textContent = text; }

function fmtBytes(n) {
  if (n === null || n === undefined) return "–";
  const u = ["B", "KiB", "MiB", "GiB"]; let i = 0; let x = n;
  while (x >= 1024 && i < u.length - 1) { x /= 1024; i++; }
  return (i ? x.toFixed(1) : x) + " " + u[i];
}
function fmtMs(ms) {
  if (ms === null || ms === undefined) return "–";
  if (ms < 1000) return Math.round(ms) + " ms";
  if (ms < 60000) return (ms / 1000).toFixed(1) + " s";
  return Math.floor(ms / 60000) + " min " + Math.round((ms % 60000) / 1000) + " s";
}
function fmtErr(e) { return e === null || e === undefined ? "–" : Number(e).toExponential(1); }
function thickness(layers) {
  return layers.map(l => l.thickness_um !== undefined ? l.thickness_um + " µm"
    : l.optical_thickness === "infinite" ? "τ ∞" : "τ " + l.optical_thickness).join(" / ");
}
function stateBadge(s) { return el("span", { class: "state " + s }, s); }
function idLink(id) { return el("a", { href: "#/result/" + id, class: "id", title: id }, id.slice(0, 12)); }

/** Load an image through `api`'s headers into an <img> (lazily, when visible). */
const lazy = "IntersectionObserver" in window ? new IntersectionObserver(entries => {
  for (const en of entries) if (en.isIntersecting) { lazy.unobserve(en.target); loadImage(en.target); }
}, { rootMargin: "200px" }) : null;
async function loadImage(img) {
  const src = img.dataset.src;
  try {
    const res = await fetch(src, { headers: headers() });
    if (!res.ok) throw new Error(res.status + " " + res.statusText);
    const url = URL.createObjectURL(await res.blob());
    img.addEventListener("load", () => { img.dataset.loaded = "true"; }, { once: true });
    img.src = url;
  } catch (e) {
    img.alt = img.alt + " (unavailable: " + e.message + ")";
    img.dataset.loaded = "error";
  }
}
function image(src, alt, cls) {
  const img = el("img", { alt, class: cls, "data-src": src, width: 64, height: 64 });
  if (lazy) lazy.observe(img); else loadImage(img);
  return img;
}

function problemBox(e) {
  return el("p", { class: "error", role: "alert" }, (e.problem && e.problem.path ? e.problem.path + ": " : ""), e.message);
}

// ---------------------------------------------------------------- queue
function queueRow(j) {
  const pct = Math.round(100 * j.progress);
  return el("tr", { "data-id": j.id, "data-status": j.status },
    el("td", {}, idLink(j.id)),
    el("td", {}, stateBadge(j.status)),
    el("td", {}, j.materials.join(", "), el("span", { class: "muted" }, " on " + j.base)),
    el("td", {}, el("progress", { max: 100, value: pct, "aria-label": "progress of " + j.id.slice(0, 12) }), " " + pct + " %"),
    el("td", {}, j.worker || "–"),
    el("td", { class: "num" }, j.status === "running" ? fmtMs(j.elapsed_ms) : fmtMs(j.solve_time_ms)),
    el("td", { class: "num" }, j.remaining_ms !== undefined ? fmtMs(j.remaining_ms) : "–"),
    el("td", { class: "num" }, j.wavelengths));
}

async function queuePage() {
  const m = main();
  m.replaceChildren(el("h2", {}, "Queue"),
    el("p", { class: "muted", id: "queue-mode" }, ""),
    el("table", { "aria-label": "Jobs" },
      el("thead", {}, el("tr", {}, ["Result", "State", "Material", "Progress", "Worker", "Wall time", "Remaining", "Wavelengths"].map(h => el("th", { scope: "col" }, h)))),
      el("tbody", { id: "jobs" })));
  const jobs = new Map();
  const order = { running: 0, queued: 1, done: 2, failed: 3 };
  function render() {
    const rows = [...jobs.values()].sort((a, b) => (order[a.status] - order[b.status]) || (b.created_at < a.created_at ? -1 : 1));
    $("#jobs").replaceChildren(...rows.slice(0, 200).map(queueRow));
    if (!rows.length) $("#jobs").append(el("tr", {}, el("td", { colspan: 8, class: "muted" }, "No jobs.")));
  }
  async function poll() {
    const [active, recent] = await Promise.all([
      api("/v1/brdfs?status=queued,running&limit=500"), api("/v1/brdfs?status=done,failed&limit=20")]);
    for (const j of [...active.body.items, ...recent.body.items]) jobs.set(j.id, j);
    for (const [id, j] of jobs) if ((j.status === "queued" || j.status === "running") && !active.body.items.some(a => a.id === id)) {
      try { jobs.set(id, (await api("/v1/brdfs?q=" + id + "&limit=1")).body.items[0] || j); } catch (_) { }
    }
    render();
  }
  try { await poll(); } catch (e) { m.append(problemBox(e)); return; }
  let timer = null, source = null;
  const startPolling = why => {
    $("#queue-mode").textContent = "Updating every 2 s (" + why + ").";
    timer = setInterval(() => poll().catch(() => { }), 2000);
  };
  if (token || !("EventSource" in window)) {
    startPolling(token ? "a token is set: event streams cannot send it" : "no EventSource");
  } else {
    source = new EventSource("/v1/events");
    $("#queue-mode").textContent = "Live (server-sent events).";
    source.addEventListener("job", ev => { const j = JSON.parse(ev.data); jobs.set(j.id, j); render(); });
    source.onerror = () => { if (source.readyState === EventSource.CLOSED && !timer) startPolling("the event stream closed"); };
  }
  leave = () => { if (source) source.close(); if (timer) clearInterval(timer); };
}

// ---------------------------------------------------------------- cache
async function cachePage(params) {
  const m = main();
  const f = {
    q: params.get("q") || "", material: params.get("material") || "", base: params.get("base") || "",
    thickness: params.get("thickness") || "", wavelength_nm: params.get("wavelength_nm") || "",
    sort: params.get("sort") || "recent",
  };
  const field = (name, label, hint) => el("div", { class: "field" },
    el("label", { for: "f-" + name }, label), el("input", { id: "f-" + name, name, value: f[name], placeholder: hint, size: 12 }));
  const form = el("form", { class: "filters", role: "search", "aria-label": "Filter results" },
    field("q", "Search", "id, material, base"), field("material", "Material", "TiO2"), field("base", "Base", "fresnel:Al"),
    field("thickness", "Thickness", "1 or 25 (µm)"), field("wavelength_nm", "Wavelength (nm)", "550"),
    el("div", { class: "field" }, el("label", { for: "f-sort" }, "Sort"),
      el("select", { id: "f-sort", name: "sort" },
        el("option", { value: "recent", selected: f.sort === "recent" }, "newest first"),
        el("option", { value: "size", selected: f.sort === "size" }, "largest first"))),
    el("button", { type: "submit" }, "Apply"));
  form.addEventListener("submit", ev => {
    ev.preventDefault();
    const p = new URLSearchParams();
    for (const [k, v] of new FormData(form)) if (String(v).trim() && !(k === "sort" && v === "recent")) p.set(k, String(v).trim());
    location.hash = "#/cache" + (p.toString() ? "?" + p : "");
  });
  const body = el("tbody", { id: "results" });
  const more = el("button", { class: "secondary", type: "button", hidden: true }, "Load more");
  m.replaceChildren(el("h2", {}, "Cache"), form,
    el("table", { "aria-label": "Results" },
      el("thead", {}, el("tr", {}, ["Intensity", "DOP", "Result", "State", "Material", "Base", "Thickness", "λ (nm)", "Size", "Solve time", "Streams", "Error est."]
        .map(h => el("th", { scope: "col", class: ["Size", "Solve time", "Streams", "Error est."].includes(h) ? "num" : null }, h)))),
      body),
    el("p", { class: "pager" }, more, " ", el("span", { id: "count", class: "muted" })));
  const q = new URLSearchParams({ limit: "50" });
  for (const [k, v] of Object.entries(f)) if (v && !(k === "sort" && v === "recent")) q.set(k, v);
  let shown = 0;
  async function page(cursor) {
    if (cursor) q.set("cursor", cursor);
    let r;
    try { r = await api("/v1/brdfs?" + q); } catch (e) { m.append(problemBox(e)); return; }
    for (const j of r.body.items) {
      const done = j.status === "done";
      body.append(el("tr", { "data-id": j.id },
        el("td", {}, done ? image(j.links.thumbnail, "sphere with " + j.id.slice(0, 12) + ", intensity", "thumb") : "–"),
        el("td", {}, done ? image(j.links.dop_thumbnail, "sphere with " + j.id.slice(0, 12) + ", degree of polarization", "thumb") : "–"),
        el("td", {}, idLink(j.id)), el("td", {}, stateBadge(j.status)),
        el("td", {}, j.materials.join(", ")), el("td", {}, j.base + (j.top_interface ? " + " + j.top_interface + " interface" : "")),
        el("td", {}, thickness(j.layers)), el("td", {}, j.wavelengths_nm.join(", ") || "–"),
        el("td", { class: "num" }, fmtBytes(j.size)), el("td", { class: "num" }, fmtMs(j.solve_time_ms)),
        el("td", { class: "num" }, j.streams !== null ? j.streams : "tol " + j.tolerance),
        el("td", { class: "num" }, fmtErr(j.error_estimate))));
    }
    shown += r.body.items.length;
    $("#count").textContent = shown + " shown" + (r.body.next ? "" : " (all)");
    more.hidden = !r.body.next;
    more.onclick = () => page(r.body.next);
    if (!shown) body.append(el("tr", {}, el("td", { colspan: 12, class: "muted" }, "No results match.")));
    // When the first page was on screen (ms since navigation): benches/console.rs.
    if (!document.body.dataset.cacheLoaded) document.body.dataset.cacheLoadedMs = performance.now().toFixed(1);
    document.body.dataset.cacheLoaded = "true";
  }
  await page(null);
}

// ---------------------------------------------------------------- result
const FORMATS = [["binary", "table (.pbrdf)"], ["npy", "NumPy .npy"], ["json", "JSON"], ["mitsuba", "Mitsuba 3 (.pbsdf)"]];

async function download(a, ev) {
  // With a token the plain link cannot authenticate: fetch and save instead.
  if (!token) return;
  ev.preventDefault();
  const res = await fetch(a.href, { headers: headers() });
  if (!res.ok) { announce("download failed: " + res.status); return; }
  const url = URL.createObjectURL(await res.blob());
  const tmp = el("a", { href: url, download: a.getAttribute("download") });
  document.body.append(tmp); tmp.click(); tmp.remove();
}

async function resultPage(id) {
  const m = main();
  m.replaceChildren(el("h2", {}, "Result ", el("span", { class: "id" }, id)));
  let r;
  try { r = (await api("/v1/brdfs/" + id)).body; } catch (e) { m.append(problemBox(e)); return; }
  const origin = location.origin;
  const specText = JSON.stringify(r.spec, null, 2);
  const copy = el("button", { type: "button", class: "secondary" }, "Copy spec");
  copy.addEventListener("click", async () => {
    try { await navigator.clipboard.writeText(specText); announce("spec copied"); } catch (_) { announce("copy refused by the browser"); }
  });
  const info = el("p", {}, stateBadge(r.status), " ",
    r.status === "done" ? `${fmtBytes(r.result.size)}, error estimate ${fmtErr(r.error_estimate)}, ${r.wavelengths} wavelength(s)` :
      r.status === "failed" ? el("span", { class: "error" }, r.error ? r.error.detail : "failed") : Math.round(100 * r.progress) + " % solved");
  const left = el("section", { "aria-label": "Spec" }, el("h3", {}, "Spec"), copy, el("pre", { id: "spec" }, specText));
  const right = el("section", { "aria-label": "Plots" });
  m.append(info, el("div", { class: "grid2" }, left, right));
  if (r.status !== "done") {
    right.append(el("p", { class: "muted" }, "Plots, downloads and timings appear when the job is done."));
    const t = setTimeout(() => { if (location.hash === "#/result/" + id) route(); }, 2000);
    leave = () => clearTimeout(t);
    return;
  }
  const meta = (await api("/v1/brdfs/" + id + "/metadata")).body;
  const wls = meta.wavelengths.map(w => w.wavelength_nm).filter(w => w !== null);
  const slider = el("input", { id: "theta-i", type: "range", min: 0, max: 85, step: 1, value: 45, "aria-describedby": "theta-i-value" });
  const value = el("output", { id: "theta-i-value", for: "theta-i" }, "45°");
  const wlSelect = wls.length > 1 ? el("select", { id: "plot-wl" }, wls.map(w => el("option", { value: w }, w + " nm"))) : null;
  const plot = el("img", { id: "plot", alt: "BRDF and DOP lobes in the plane of incidence", width: 720, height: 640 });
  let pending = null;
  const redraw = () => {
    value.textContent = slider.value + "°";
    clearTimeout(pending);
    pending = setTimeout(() => {
      let src = `/v1/brdfs/${id}/plot?theta_i_deg=${slider.value}`;
      if (wlSelect) src += "&wavelength_nm=" + wlSelect.value;
      plot.dataset.src = src; plot.dataset.loaded = "";
      loadImage(plot);
    }, 120);
  };
  slider.addEventListener("input", redraw);
  if (wlSelect) wlSelect.addEventListener("change", redraw);
  right.append(el("h3", {}, "Lobes"),
    el("p", {}, el("label", { for: "theta-i" }, "Incident angle θi "), slider, " ", value,
      wlSelect ? [" ", el("label", { for: "plot-wl" }, "wavelength "), wlSelect] : null),
    el("div", { class: "plot" }, plot),
    el("h3", {}, "Thumbnails"),
    el("p", {}, image(r.links.self + "/thumbnail?kind=intensity", "sphere, intensity", "thumb"), " ",
      image(r.links.self + "/thumbnail?kind=dop", "sphere, degree of polarization", "thumb")));
  redraw();
  const perWl = el("table", { "aria-label": "Per-wavelength error and time" },
    el("thead", {}, el("tr", {}, ["Wavelength (nm)", "Streams", "Fourier orders", "Wall time", "Error estimate"].map(h => el("th", { scope: "col" }, h)))),
    el("tbody", {}, meta.wavelengths.map(w => el("tr", {},
      el("td", {}, w.wavelength_nm === null ? "–" : w.wavelength_nm), el("td", { class: "num" }, w.streams),
      el("td", { class: "num" }, w.fourier_orders), el("td", { class: "num" }, fmtMs(w.wall_time_ms)),
      el("td", { class: "num" }, w.error_estimate ? fmtErr(w.error_estimate.max_err_f11) : "–")))));
  const links = el("ul", { id: "downloads" }, FORMATS.map(([fmt, label]) => {
    const href = `/v1/brdfs/${id}/table` + (fmt === "binary" ? "" : "?format=" + fmt);
    const name = id.slice(0, 12) + { binary: ".pbrdf", npy: ".npy", json: ".json", mitsuba: ".pbsdf" }[fmt];
    const a = el("a", { href, download: name, "data-format": fmt }, label);
    a.addEventListener("click", ev => download(a, ev));
    return el("li", {}, a);
  }));
  const auth = token ? ` -H "Authorization: Bearer $POLBRDF_TOKEN"` : "";
  const curl = `curl -fsS${auth} -o ${id.slice(0, 12)}.pbrdf ${origin}/v1/brdfs/${id}/table\n` +
    `curl -fsS${auth} "${origin}/v1/brdfs/${id}/eval?theta_i_deg=45&phi_i_deg=0&theta_o_deg=30&phi_o_deg=180"`;
  const py = `import json, urllib.request\n\nurl = "${origin}/v1/brdfs/${id}"\n` +
    `req = lambda path: urllib.request.Request(url + path${token ? ', headers={"Authorization": "Bearer " + TOKEN}' : ""})\n` +
    `with urllib.request.urlopen(req("/table")) as r:\n    open("${id.slice(0, 12)}.pbrdf", "wb").write(r.read())\n` +
    `q = "?theta_i_deg=45&phi_i_deg=0&theta_o_deg=30&phi_o_deg=180"\n` +
    `with urllib.request.urlopen(req("/eval" + q)) as r:\n    print(json.load(r)["mueller"])`;
  left.append(el("h3", {}, "Per wavelength"), perWl, el("h3", {}, "Downloads"), links,
    el("h3", {}, "curl"), el("pre", { id: "snippet-curl" }, curl), el("h3", {}, "Python"), el("pre", { id: "snippet-python" }, py));
}

// ---------------------------------------------------------------- submit
async function submitPage() {
  const m = main();
  let examples = [];
  try { examples = (await api("/console/examples.json")).body; } catch (_) { }
  const editor = el("textarea", { id: "spec-editor", spellcheck: "false", "aria-describedby": "submit-result", "aria-label": "Material spec (JSON)" });
  editor.value = examples.length ? JSON.stringify(examples[0].spec, null, 2) : "{\n}";
  const pick = el("select", { id: "template" }, examples.map((e, i) => el("option", { value: i }, e.name)));
  pick.addEventListener("change", () => { editor.value = JSON.stringify(examples[pick.value].spec, null, 2); editor.removeAttribute("aria-invalid"); });
  const out = el("div", { id: "submit-result", "aria-live": "polite" });
  const form = el("form", { id: "submit-form" },
    el("p", {}, el("label", { for: "template" }, "Template (api/examples) "), pick),
    editor,
    el("p", {}, el("button", { type: "submit" }, "Submit"), " ",
      el("span", { class: "muted" }, token ? "with the token entered above" : "without a token")));
  form.addEventListener("submit", async ev => {
    ev.preventDefault();
    out.replaceChildren(el("p", { class: "muted" }, "Submitting…"));
    editor.removeAttribute("aria-invalid");
    try {
      const { body } = await api("/v1/brdfs", { method: "POST", headers: { "Content-Type": "application/json" }, body: editor.value });
      out.replaceChildren(el("p", { class: "ok" }, "Accepted: ", idLink(body.id), " (" + body.status + ")"));
      location.hash = "#/result/" + body.id;
    } catch (e) {
      out.replaceChildren(problemBox(e));
      if (e.problem && e.problem.path) { editor.setAttribute("aria-invalid", "true"); pointAt(editor, e.problem.path); }
    }
  });
  m.replaceChildren(el("h2", {}, "Submit a spec"),
    el("p", { class: "muted" }, "docs/spec.md describes the fields; errors name the JSON path."), form, out);
}

/** Select the last named key of a JSON path (`layers[0].scatterer.mie.radius_um`) in the editor. */
function pointAt(editor, path) {
  const keys = path.split(/[.[\]]/).filter(k => k && !/^\d+$/.test(k) && k !== "?");
  const text = editor.value;
  let at = 0;
  for (const k of keys) { const i = text.indexOf('"' + k + '"', at); if (i >= 0) at = i; }
  const key = keys[keys.length - 1];
  if (key && text.indexOf('"' + key + '"', at) === at) {
    editor.focus(); editor.setSelectionRange(at + 1, at + 1 + key.length);
  }
}

// ---------------------------------------------------------------- routing
async function route() {
  leave(); leave = () => { };
  const [path, query] = (location.hash.slice(1) || "/queue").split("?");
  const params = new URLSearchParams(query || "");
  const parts = path.split("/").filter(Boolean);
  const page = parts[0] || "queue";
  for (const a of document.querySelectorAll("nav a")) {
    if (a.dataset.page === page) a.setAttribute("aria-current", "page"); else a.removeAttribute("aria-current");
  }
  document.title = "polbrdf · " + page;
  try {
    if (page === "cache") await cachePage(params);
    else if (page === "result" && parts[1]) await resultPage(parts[1]);
    else if (page === "submit") await submitPage();
    else await queuePage();
  } catch (e) {
    main().append(problemBox(e));
  }
  document.body.dataset.page = page;
}

window.addEventListener("hashchange", route);
document.addEventListener("DOMContentLoaded", () => {
  $("#token").value = token;
  $("#token-form").addEventListener("submit", ev => {
    ev.preventDefault();
    token = $("#token").value.trim();
    if (token) sessionStorage.setItem("polbrdf-token", token); else sessionStorage.removeItem("polbrdf-token");
    announce(token ? "token set" : "token cleared");
    route();
  });
  route();
});
