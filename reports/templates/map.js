/* orthospec findings map: pan, zoom, click for the QCR records. No network, no innerHTML. */
(function () {
  "use strict";
  var box = document.getElementById("findings-map");
  var island = document.getElementById("findings-data");
  if (!box || !island) { return; }
  var svg = box.querySelector("svg");
  var panel = document.getElementById("map-panel");
  var data = JSON.parse(island.textContent);
  var vb = svg.getAttribute("viewBox").split(" ").map(Number);
  var view = vb.slice();
  function apply() { svg.setAttribute("viewBox", view.join(" ")); }
  function el(tag, text, cls) {
    var e = document.createElement(tag);
    if (text !== undefined) { e.textContent = text; }
    if (cls) { e.className = cls; }
    return e;
  }
  function show(key) {
    var f = data[key];
    if (!f) { return; }
    while (panel.firstChild) { panel.removeChild(panel.firstChild); }
    panel.appendChild(el("h4", f.layer + " " + f.id + ": " + f.verdict));
    var t = el("table", undefined, "data map-props");
    f.props.forEach(function (p) {
      var tr = el("tr"); tr.appendChild(el("th", p[0])); tr.appendChild(el("td", p[1])); t.appendChild(tr);
    });
    panel.appendChild(t);
    var r = el("table", undefined, "data map-records");
    var head = el("tr");
    ["Rule", "Verdict", "Message", "Clause"].forEach(function (h) { head.appendChild(el("th", h)); });
    r.appendChild(head);
    f.records.forEach(function (q) {
      var tr = el("tr", undefined, "qcr v-" + q[1]);
      q.forEach(function (c) { tr.appendChild(el("td", c)); });
      r.appendChild(tr);
    });
    if (!f.records.length) { panel.appendChild(el("p", "No quality control record names this feature.")); }
    else { panel.appendChild(r); }
    var old = svg.querySelector(".selected");
    if (old) { old.classList.remove("selected"); }
    var sel = svg.querySelector('[data-k="' + key.replace(/"/g, "") + '"]');
    if (sel) { sel.classList.add("selected"); }
  }
  function point(evt) {
    var rect = svg.getBoundingClientRect();
    return [view[0] + (evt.clientX - rect.left) / rect.width * view[2],
            view[1] + (evt.clientY - rect.top) / rect.height * view[3]];
  }
  svg.addEventListener("wheel", function (evt) {
    evt.preventDefault();
    var p = point(evt), s = evt.deltaY > 0 ? 1.25 : 0.8;
    if (view[2] * s > vb[2] * 4 || view[2] * s < vb[2] / 400) { return; }
    view = [p[0] - (p[0] - view[0]) * s, p[1] - (p[1] - view[1]) * s, view[2] * s, view[3] * s];
    apply();
  }, {passive: false});
  var drag = null, moved = false;
  svg.addEventListener("pointerdown", function (evt) { drag = [evt.clientX, evt.clientY, view[0], view[1]]; moved = false; });
  window.addEventListener("pointerup", function () { drag = null; });
  svg.addEventListener("pointermove", function (evt) {
    if (!drag) { return; }
    var rect = svg.getBoundingClientRect();
    var dx = evt.clientX - drag[0], dy = evt.clientY - drag[1];
    if (Math.abs(dx) + Math.abs(dy) > 3) { moved = true; }
    view[0] = drag[2] - dx / rect.width * view[2];
    view[1] = drag[3] - dy / rect.height * view[3];
    apply();
  });
  svg.addEventListener("click", function (evt) {
    if (moved) { return; }
    var t = evt.target.closest("[data-k]");
    if (t) { show(t.getAttribute("data-k")); }
  });
  svg.addEventListener("dblclick", function () { view = vb.slice(); apply(); });
}());
