// kinecal workbench: what the page adds to viser's client (kinecal/ui/front.py).
// 1. Files dropped anywhere on the page go to the workbench (POST /kinecal/drop); its
//    answer (what it loaded, or the command line's error text) shows in #kc-drop-message.
// 2. Links of class kc-open (a report; data-pair: a second one side by side) open over
//    the 3D view in #kc-overlay instead of leaving the page.
(function () {
  "use strict";

  function el(tag, attrs, text) {
    var e = document.createElement(tag);
    Object.keys(attrs || {}).forEach(function (k) { e.setAttribute(k, attrs[k]); });
    if (text) e.textContent = text;
    return e;
  }

  var shade = el("div", { id: "kc-drop-shade" }, "Drop a model, measurements, a plan or a result");
  var note = el("div", { id: "kc-drop-message", role: "status" });
  var overlay = el("div", { id: "kc-overlay" });
  var bar = el("div", { class: "kc-overlay-bar" });
  var close = el("button", { id: "kc-overlay-close", type: "button" }, "Close");
  var panes = el("div", { class: "kc-overlay-panes" });
  bar.appendChild(close);
  overlay.appendChild(bar);
  overlay.appendChild(panes);

  function mount() {
    document.body.appendChild(shade);
    document.body.appendChild(note);
    document.body.appendChild(overlay);
  }
  if (document.body) mount(); else document.addEventListener("DOMContentLoaded", mount);

  function show(ok, text) {
    note.textContent = text;
    note.className = ok ? "kc-ok" : "kc-error";
    note.style.display = "block";
    clearTimeout(show.timer);
    if (ok) show.timer = setTimeout(function () { note.style.display = "none"; }, 8000);
  }
  note.addEventListener("click", function () { note.style.display = "none"; });

  function send(file) {
    return fetch("/kinecal/drop?name=" + encodeURIComponent(file.name), {
      method: "POST", body: file,
    }).then(function (r) { return r.json(); })
      .then(function (a) { show(a.ok, a.message); return a; })
      .catch(function (e) { show(false, "kinecal: error: " + file.name + ": " + e); });
  }
  window.kinecalDrop = send;  // for scripts and tests: the same path as a drop

  var depth = 0;
  function hasFiles(ev) {
    var t = ev.dataTransfer && ev.dataTransfer.types;
    return t && Array.prototype.indexOf.call(t, "Files") >= 0;
  }
  window.addEventListener("dragenter", function (ev) {
    if (!hasFiles(ev)) return;
    depth += 1; shade.style.display = "flex"; ev.preventDefault();
  }, true);
  window.addEventListener("dragleave", function () {
    depth = Math.max(0, depth - 1);
    if (depth === 0) shade.style.display = "none";
  }, true);
  window.addEventListener("dragover", function (ev) {
    if (hasFiles(ev)) ev.preventDefault();
  }, true);
  window.addEventListener("drop", function (ev) {
    if (!hasFiles(ev)) return;
    ev.preventDefault(); ev.stopPropagation();
    depth = 0; shade.style.display = "none";
    var files = Array.prototype.slice.call(ev.dataTransfer.files);
    files.reduce(function (p, f) { return p.then(function () { return send(f); }); },
                 Promise.resolve());
  }, true);

  function open(urls) {
    panes.innerHTML = "";
    urls.forEach(function (u) {
      var f = el("iframe", { src: u, class: "kc-report" });
      panes.appendChild(f);
    });
    overlay.style.display = "flex";
  }
  close.addEventListener("click", function () {
    overlay.style.display = "none"; panes.innerHTML = "";
  });
  document.addEventListener("click", function (ev) {
    var a = ev.target && ev.target.closest && ev.target.closest("a.kc-open");
    if (!a) return;
    ev.preventDefault();
    var urls = [a.getAttribute("href")];
    if (a.dataset.pair) urls.push(a.dataset.pair);
    open(urls);
  }, true);
})();
