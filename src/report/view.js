// kinecal report: the 3-D view (see src/report/view.rs). Orthographic projection of the
// measured tool positions (for an instrument's rows, the model's tool points), their error
// vectors, the frames, an instrument's artifacts and the machine's skeleton on a canvas; drag
// turns, shift-drag moves, the wheel zooms, hovering names a pose.
(function () {
  "use strict";
  var data = JSON.parse(document.getElementById("view-data").textContent);
  var cv = document.getElementById("view3d");
  var tip = document.getElementById("view-tip");
  var ctx = cv.getContext("2d");
  var W = cv.width, H = cv.height;
  var state = { yaw: -0.7, pitch: 0.45, zoom: 1, panX: 0, panY: 0, mode: "after", vectors: true, scale: 0, show: {} };
  var sets = data.sets;
  var artifacts = data.artifacts || [];
  sets.forEach(function (s) { state.show[s.name] = true; });

  // Scene centre and radius: every point, the skeleton, the artifacts, the measurement frame's origin.
  var pts = [];
  if (data.base) pts.push([data.base[0], data.base[1], data.base[2]]);
  sets.forEach(function (s) {
    [s.p, s.pb || []].forEach(function (p) { for (var k = 0; k + 2 < p.length; k += 3) if (p[k] !== null) pts.push([p[k], p[k + 1], p[k + 2]]); });
  });
  // An artifact's extent: its frame's origin, and a plane's patch or the cube's corners.
  artifacts.forEach(function (a) {
    [a.f, a.n].forEach(function (g) {
      var e = a.kind === "plane" ? a.size : a.kind === "cube" ? a.size / 2 : 0;
      [[0, 0, 0], [e, e, 0], [-e, -e, 0], [e, -e, 0], [-e, e, 0], [e, e, e], [-e, -e, -e]].forEach(function (x) { pts.push(local(g, x[0], x[1], x[2])); });
    });
  });
  data.skeleton.forEach(function (l) { for (var k = 0; k + 2 < l.length; k += 3) pts.push([l[k], l[k + 1], l[k + 2]]); });
  var lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
  pts.forEach(function (p) { for (var a = 0; a < 3; a++) { if (p[a] === null) return; lo[a] = Math.min(lo[a], p[a]); hi[a] = Math.max(hi[a], p[a]); } });
  if (!pts.length) { pts.push([0, 0, 0]); lo = [0, 0, 0]; hi = [0, 0, 0]; }
  var C = [0, 1, 2].map(function (a) { return (lo[a] + hi[a]) / 2; });
  var R = 1;
  pts.forEach(function (p) { if (p[0] !== null) R = Math.max(R, Math.hypot(p[0] - C[0], p[1] - C[1], p[2] - C[2])); });

  function nice(v) {
    if (!(v > 0) || !isFinite(v)) return 1;
    var m = Math.pow(10, Math.floor(Math.log10(v)));
    var f = v / m;
    return (f < 1.5 ? 1 : f < 3.5 ? 2 : f < 7.5 ? 5 : 10) * m;
  }
  function quantile(values, q) {
    var v = values.filter(function (x) { return x !== null && isFinite(x); }).sort(function (a, b) { return a - b; });
    return v.length ? v[Math.min(v.length - 1, Math.floor(q * (v.length - 1)))] : 0;
  }
  function magnitudes(key) { var out = []; sets.forEach(function (s) { out = out.concat(s[key]); }); return out; }
  // Error vectors: scaled so that the 95th percentile is 8 % of the scene, a round factor.
  function autoScale() {
    var q = quantile(magnitudes(state.mode === "after" ? "a" : "b"), 0.95);
    return q > 1e-6 ? nice(0.08 * R / q) : 1;
  }
  var scaleInput = document.getElementById("view-scale");
  function resetScale() { state.scale = autoScale(); if (scaleInput) scaleInput.value = String(state.scale); }
  resetScale();

  function project(p) {
    var x = p[0] - C[0], y = p[1] - C[1], z = p[2] - C[2];
    var cy = Math.cos(state.yaw), sy = Math.sin(state.yaw), cp = Math.cos(state.pitch), sp = Math.sin(state.pitch);
    var x1 = cy * x - sy * y, y1 = sy * x + cy * y;
    var up = cp * z + sp * y1, depth = sp * z - cp * y1;
    var s = pixels();
    return [W / 2 + state.panX + s * x1, H / 2 + state.panY - s * up, depth];
  }
  // Pixels per mm.
  function pixels() { return state.zoom * Math.min(W, H) / (2.3 * R); }
  // Colour map (blue, cyan, green, yellow, red) over [0, top].
  var STOPS = [[49, 54, 149], [69, 117, 180], [116, 196, 118], [254, 224, 80], [215, 48, 39]];
  function colour(v, top) {
    var t = Math.max(0, Math.min(1, v / (top || 1))) * (STOPS.length - 1);
    var k = Math.min(STOPS.length - 2, Math.floor(t)), f = t - k;
    var c = STOPS[k].map(function (a, j) { return Math.round(a + f * (STOPS[k + 1][j] - a)); });
    return "rgb(" + c.join(",") + ")";
  }
  function fmt(v) { return v === null || v === undefined ? "—" : Math.abs(v) >= 100 ? v.toFixed(1) : v.toPrecision(3); }

  var drawn = [];
  function line(a, b, colourName, width, dash) {
    ctx.strokeStyle = colourName; ctx.lineWidth = width; ctx.setLineDash(dash || []);
    ctx.beginPath(); ctx.moveTo(a[0], a[1]); ctx.lineTo(b[0], b[1]); ctx.stroke(); ctx.setLineDash([]);
  }
  function frame(origin, axes, len, label, below) {
    var o = project(origin);
    ["#d62728", "#2ca02c", "#1f77b4"].forEach(function (c, a) {
      var e = project([origin[0] + len * axes[a][0], origin[1] + len * axes[a][1], origin[2] + len * axes[a][2]]);
      line(o, e, c, 2);
      ctx.fillStyle = c; ctx.font = "11px sans-serif"; ctx.fillText("xyz"[a], e[0] + 3, e[1] - 3);
    });
    ctx.fillStyle = "#222"; ctx.font = "12px sans-serif"; ctx.fillText(label, o[0] + 4, o[1] + (below ? 14 : -8));
  }
  function polyline(flat, colourName, width, dash) {
    for (var k = 0; k + 5 < flat.length; k += 3) {
      line(project([flat[k], flat[k + 1], flat[k + 2]]), project([flat[k + 3], flat[k + 4], flat[k + 5]]), colourName, width, dash);
    }
  }
  // A point of an artifact's frame g (origin, x, y, z axes, flat) at local coordinates (u, v, w).
  function local(g, u, v, w) {
    return [0, 1, 2].map(function (a) { return g[a] + u * g[3 + a] + v * g[6 + a] + w * g[9 + a]; });
  }
  // An artifact drawn from its frame g: a seat as a ring, a pivot as a square, a sphere as its
  // outline, a plane as a square patch over its touches, the cube as its edges.
  function artifact(a, g, colourName, dash) {
    var o = project([g[0], g[1], g[2]]);
    ctx.strokeStyle = colourName; ctx.lineWidth = dash ? 1.2 : 2; ctx.setLineDash(dash || []);
    if (a.kind === "seat") {
      ctx.beginPath(); ctx.arc(o[0], o[1], 6, 0, 2 * Math.PI); ctx.stroke();
    } else if (a.kind === "pivot") {
      ctx.strokeRect(o[0] - 5, o[1] - 5, 10, 10);
    } else if (a.kind === "sphere") {
      ctx.beginPath(); ctx.arc(o[0], o[1], Math.max(3, pixels() * a.size / 2), 0, 2 * Math.PI); ctx.stroke();
    } else if (a.kind === "plane") {
      var c = [[1, 1], [-1, 1], [-1, -1], [1, -1]].map(function (x) { return project(local(g, a.size * x[0], a.size * x[1], 0)); });
      ctx.beginPath(); ctx.moveTo(c[0][0], c[0][1]);
      for (var k = 1; k < 4; k++) ctx.lineTo(c[k][0], c[k][1]);
      ctx.closePath(); ctx.stroke();
      if (!dash) { ctx.fillStyle = "rgba(20,120,120,0.08)"; ctx.fill(); }
    } else if (a.kind === "cube") {
      var e = a.size / 2;
      for (var axis = 0; axis < 3; axis++) {
        [[-1, -1], [-1, 1], [1, -1], [1, 1]].forEach(function (x) {
          var u = [0, 0, 0], v = [0, 0, 0];
          u[axis] = -e; v[axis] = e; u[(axis + 1) % 3] = v[(axis + 1) % 3] = x[0] * e; u[(axis + 2) % 3] = v[(axis + 2) % 3] = x[1] * e;
          var p = project(local(g, u[0], u[1], u[2])), q = project(local(g, v[0], v[1], v[2]));
          ctx.beginPath(); ctx.moveTo(p[0], p[1]); ctx.lineTo(q[0], q[1]); ctx.stroke();
        });
      }
    }
    ctx.setLineDash([]);
  }
  var ARTIFACT = "#137a7a";

  function draw() {
    ctx.fillStyle = "#fff"; ctx.fillRect(0, 0, W, H);
    var key = state.mode === "after" ? "a" : "b", vkey = state.mode === "after" ? "ea" : "eb";
    // The colour scale ends at the 98th percentile (redder beyond), so a few blunders do not
    // wash the rest out.
    var top = quantile(magnitudes(key), 0.98), most = quantile(magnitudes(key), 1);
    // Frames and skeleton first, points over them.
    var axis = nice(0.12 * R);
    frame([0, 0, 0], [[1, 0, 0], [0, 1, 0], [0, 0, 1]], axis, (data.world || "measurement frame") + " (axes " + axis + " mm)", true);
    if (data.base) {
      var b = data.base;
      frame([b[0], b[1], b[2]], [[b[3], b[4], b[5]], [b[6], b[7], b[8]], [b[9], b[10], b[11]]], axis, "base");
    }
    // An instrument's artifacts: as the starting model placed them (dashed), then fitted.
    artifacts.forEach(function (a) { artifact(a, a.n, "#999", [4, 3]); });
    artifacts.forEach(function (a) { artifact(a, a.f, ARTIFACT, null); });
    drawn = [];
    sets.forEach(function (s, si) {
      if (!state.show[s.name]) return;
      for (var j = 0; j < s.i.length; j++) {
        // An instrument's row (artifact k ≥ 0): the model's tool point, the starting model's
        // before calibration; its error vector points from it toward where the instrument puts it.
        var k = s.k ? s.k[j] : -1, from = k >= 0 && state.mode !== "after" && s.pb ? s.pb : s.p;
        var p = [from[3 * j], from[3 * j + 1], from[3 * j + 2]];
        if (p[0] === null) continue;
        var q = project(p);
        var e = s[vkey] ? [s[vkey][3 * j], s[vkey][3 * j + 1], s[vkey][3 * j + 2]] : [null];
        drawn.push({ x: q[0], y: q[1], d: q[2], s: si, j: j, v: s[key] ? s[key][j] : null, e: e, p: p, k: k });
      }
    });
    drawn.sort(function (a, b) { return a.d - b.d; });
    // A ballbar's bar: from its pivot to each of its tool points.
    drawn.forEach(function (o) {
      var a = artifacts[o.k];
      if (!a || a.kind !== "pivot") return;
      var g = state.mode === "after" ? a.f : a.n;
      line(project([g[0], g[1], g[2]]), [o.x, o.y], "rgba(19,122,122,0.25)", 1);
    });
    drawn.forEach(function (o) {
      var set = sets[o.s], c = set.colour || colour(o.v, top), r = set.size || 3.5;
      if (state.vectors && o.e[0] !== null) {
        var k = o.k >= 0 ? -state.scale : state.scale;
        var t = project([o.p[0] - k * o.e[0], o.p[1] - k * o.e[1], o.p[2] - k * o.e[2]]);
        line([o.x, o.y], t, c, 1);
      }
      if (set.name !== "validation") {
        ctx.fillStyle = c; ctx.beginPath(); ctx.arc(o.x, o.y, r, 0, 2 * Math.PI); ctx.fill();
      } else {
        ctx.strokeStyle = c; ctx.lineWidth = 1.5; ctx.strokeRect(o.x - r, o.y - r, 2 * r, 2 * r);
      }
      if (set.tag) { ctx.fillStyle = "#222"; ctx.font = "11px sans-serif"; ctx.fillText(set.tag[o.j], o.x + r + 2, o.y - r); }
    });
    // The machine over the points, the artifacts' names over everything.
    data.nominal.forEach(function (l) { polyline(l, "#999", 1.5, [5, 4]); });
    data.skeleton.forEach(function (l) { polyline(l, "rgba(40,40,40,0.85)", 4); });
    artifacts.forEach(function (a) {
      var o = project([a.f[0], a.f[1], a.f[2]]);
      ctx.fillStyle = ARTIFACT; ctx.font = "11px sans-serif"; ctx.fillText(a.name, o[0] + 8, o[1] + 12);
    });
    // The tool frame over the points too.
    if (data.tool) {
      var t = data.tool;
      frame([t[0], t[1], t[2]], [[t[3], t[4], t[5]], [t[6], t[7], t[8]], [t[9], t[10], t[11]]], axis / 2, "tool at pose id " + data.toolPose);
    }
    // The skeleton's vertices whose place the calibration changed most (three, when they moved at all).
    var moved = [];
    data.skeleton.forEach(function (l, j) {
      var m = data.moved[j];
      if (!m) return;
      for (var k = 0; k + 2 < l.length; k += 3) moved.push([m[k / 3], [l[k], l[k + 1], l[k + 2]]]);
    });
    moved.sort(function (a, b) { return b[0] - a[0]; });
    moved.slice(0, 3).forEach(function (m) {
      if (!(m[0] > 1e-6)) return;
      var q = project(m[1]);
      ctx.strokeStyle = "#c000c0"; ctx.lineWidth = 2; ctx.beginPath(); ctx.arc(q[0], q[1], 7, 0, 2 * Math.PI); ctx.stroke();
      ctx.fillStyle = "#c000c0"; ctx.font = "11px sans-serif"; ctx.fillText("changed " + fmt(m[0]) + " mm", q[0] + 9, q[1] - 6);
    });
    // Legend of the sets with a fixed colour; the colour bar and the vectors' scale when a set is
    // coloured by its errors.
    var x0 = W - 340, y0 = 16;
    var legend = sets.filter(function (s) { return s.colour; });
    legend.forEach(function (s, k) {
      ctx.fillStyle = s.colour; ctx.beginPath(); ctx.arc(x0 + 6, y0 + 6 + 18 * k, s.size || 3.5, 0, 2 * Math.PI); ctx.fill();
      ctx.fillStyle = "#222"; ctx.font = "12px sans-serif"; ctx.fillText(s.name + " (" + s.n + ")", x0 + 16, y0 + 10 + 18 * k);
    });
    if (legend.length < sets.length) {
      for (var i = 0; i < 200; i++) { ctx.fillStyle = colour(i / 199 * top, top); ctx.fillRect(x0 + i, y0, 1, 12); }
      ctx.fillStyle = "#222"; ctx.font = "12px sans-serif";
      ctx.fillText("0", x0 - 4, y0 + 26); ctx.fillText(fmt(top) + (most > top ? "+ mm (max " + fmt(most) + ")" : " mm"), x0 + 150, y0 + 26);
      ctx.fillText("position error " + (state.mode === "after" ? "after" : "before") + " calibration", x0, y0 + 42);
      if (state.vectors) ctx.fillText("error vectors ×" + state.scale + (artifacts.length ? " (toward the instrument's place)" : " (toward the model's position)"), x0, y0 + 58);
    }
    ctx.fillStyle = "#222"; ctx.font = "12px sans-serif";
    var o = project([0, 0, 0]);
    var off = o[0] < 0 || o[0] > W || o[1] < 0 || o[1] > H;
    ctx.fillText(drawn.length + " poses drawn" + (off ? "; the measurement frame's origin is off the view (wheel to zoom out)" : ""), 10, H - 10);
    cv.setAttribute("data-drawn", String(drawn.length));
  }

  var pending = false;
  function redraw() { if (!pending) { pending = true; requestAnimationFrame(function () { pending = false; draw(); }); } }

  var drag = null;
  cv.addEventListener("mousedown", function (e) { drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey }; cv.style.cursor = "grabbing"; });
  window.addEventListener("mouseup", function () { drag = null; cv.style.cursor = "grab"; });
  function canvasXY(e) { var r = cv.getBoundingClientRect(); return [(e.clientX - r.left) * W / r.width, (e.clientY - r.top) * H / r.height]; }
  cv.addEventListener("mousemove", function (e) {
    if (drag) {
      var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      if (drag.pan) { state.panX += dx; state.panY += dy; } else {
        state.yaw += 0.01 * dx;
        state.pitch = Math.max(-Math.PI / 2, Math.min(Math.PI / 2, state.pitch + 0.01 * dy));
      }
      tip.style.display = "none";
      redraw();
      return;
    }
    var m = canvasXY(e), best = null, bd = 64;
    drawn.forEach(function (o) { var d = (o.x - m[0]) * (o.x - m[0]) + (o.y - m[1]) * (o.y - m[1]); if (d < bd) { bd = d; best = o; } });
    if (!best) { tip.style.display = "none"; return; }
    var s = sets[best.s], j = best.j, text;
    if (s.label) text = s.label[j] + "\nat (" + best.p.map(function (v) { return v.toFixed(1); }).join(", ") + ") mm";
    else text = s.name + " pose id " + s.id[j] + " (row " + s.i[j] + ")" + (artifacts[best.k] ? ", " + artifacts[best.k].name : "") + "\nposition error after " + fmt(s.a[j]) + " mm, before " + fmt(s.b[j]) + " mm";
    if (!s.label && s.oa) text += "\norientation error after " + fmt(s.oa[j]) + " deg, before " + fmt(s.ob[j]) + " deg";
    if (!s.label) text += "\nat (" + best.p.map(function (v) { return v.toFixed(1); }).join(", ") + ") mm";
    tip.textContent = text;
    tip.style.left = (e.clientX - cv.getBoundingClientRect().left + 12) + "px";
    tip.style.top = (e.clientY - cv.getBoundingClientRect().top + 12) + "px";
    tip.style.display = "block";
  });
  cv.addEventListener("mouseleave", function () { tip.style.display = "none"; });
  cv.addEventListener("wheel", function (e) { e.preventDefault(); state.zoom *= Math.exp(-0.0015 * e.deltaY); redraw(); }, { passive: false });
  var VIEWS = { iso: [-0.7, 0.45], xy: [0, Math.PI / 2], xz: [0, 0], yz: [-Math.PI / 2, 0] };
  Array.prototype.forEach.call(document.querySelectorAll("#view-controls button[data-view]"), function (b) {
    b.addEventListener("click", function () { var v = VIEWS[b.getAttribute("data-view")]; state.yaw = v[0]; state.pitch = v[1]; state.zoom = 1; state.panX = state.panY = 0; redraw(); });
  });
  Array.prototype.forEach.call(document.querySelectorAll("input[name=view-mode]"), function (r) {
    r.addEventListener("change", function () { state.mode = r.value; resetScale(); redraw(); });
  });
  var vectorsBox = document.getElementById("view-vectors");
  if (vectorsBox) vectorsBox.addEventListener("change", function (e) { state.vectors = e.target.checked; redraw(); });
  else state.vectors = false;
  if (scaleInput) scaleInput.addEventListener("change", function () { var v = parseFloat(scaleInput.value); if (v >= 0) { state.scale = v; redraw(); } });
  ["identification", "validation"].forEach(function (name) {
    var box = document.getElementById("view-" + name);
    if (!box) return;
    if (!sets.some(function (s) { return s.name === name; })) { box.parentNode.style.display = "none"; return; }
    box.addEventListener("change", function (e) { state.show[name] = e.target.checked; redraw(); });
  });
  var t0 = performance.now();
  draw();
  cv.setAttribute("data-ms", String(Math.round(performance.now() - t0)));
})();
