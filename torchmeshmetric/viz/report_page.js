// The page's script (torchmeshmetric.viz.html_report): sortable tables, and a small WebGL viewer of the
// error-coloured meshes (each layer one indexed mesh with per-vertex colours and normals, a headlight, an orbit
// camera). Plain ES5, no library, nothing loaded: the page works from file:// offline.

// Sort a table by a click on a header: numbers (the report's printed digits) as numbers, other cells as text.
// A cell's number is read after the marks the reports put before it: "~" (digits --determinacy did not hold) and a
// verdict's "NAME: " or "≈: " ("~A: -0.0003 ± 0.0009" sorts by -0.0003). Numbers come before text, in both orders.
function sortKey(text) {
  var t = text.replace(/\*/g, "").trim(), n = t.replace(/^~/, "").replace(/^.*?:\s+(?=~?[-+]?(\d|\.\d|inf))/, "");
  n = n.replace(/^~/, "");
  if (/^[-+]?inf\b/.test(n)) return n.charAt(0) === "-" ? -Infinity : Infinity;
  var x = parseFloat(n);
  return isNaN(x) ? t : x;
}
function compareKeys(x, y) {
  var nx = typeof x === "number", ny = typeof y === "number";
  if (nx && ny) return x === y ? 0 : (x < y ? -1 : 1);
  if (nx !== ny) return nx ? -1 : 1;
  return String(x).localeCompare(String(y));
}
document.querySelectorAll("table.sortable th").forEach(function (th) {
  th.addEventListener("click", function () {
    var table = th.closest("table"), body = table.tBodies[0], col = th.cellIndex;
    var asc = !th.classList.contains("asc");
    table.querySelectorAll("th").forEach(function (h) { h.classList.remove("asc", "desc"); });
    th.classList.add(asc ? "asc" : "desc");
    var key = function (row) { return sortKey(row.cells[col] ? row.cells[col].textContent : ""); };
    var rows = Array.from(body.rows).map(function (row) { return [key(row), row]; });
    rows.sort(function (a, b) {
      var c = compareKeys(a[0], b[0]);
      return c === 0 ? 0 : (asc ? c : (typeof a[0] === "number") !== (typeof b[0] === "number") ? c : -c);
    }).forEach(function (pair) { body.appendChild(pair[1]); });
  });
});

// The viewer (only on a page with meshes).
(function () {
  var source = document.getElementById("tmm-meshes");
  if (!source) return;
  var layers = JSON.parse(source.textContent);
  var canvas = document.getElementById("tmm-canvas");
  var opts = {preserveDrawingBuffer: true, antialias: true};
  var gl = canvas.getContext("webgl2", opts) || canvas.getContext("webgl", opts);
  if (!gl) { canvas.insertAdjacentHTML("afterend", "<p>WebGL is not available in this browser.</p>"); return; }
  var wide = (typeof WebGL2RenderingContext !== "undefined" && gl instanceof WebGL2RenderingContext) ||
             !!gl.getExtension("OES_element_index_uint");
  function bytes(s) {
    var b = atob(s), u = new Uint8Array(b.length);
    for (var i = 0; i < b.length; i++) u[i] = b.charCodeAt(i);
    return u.buffer;
  }
  function shader(type, src) {
    var s = gl.createShader(type); gl.shaderSource(s, src); gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
    return s;
  }
  var prog = gl.createProgram();
  gl.attachShader(prog, shader(gl.VERTEX_SHADER,
    "attribute vec3 p; attribute vec3 n; attribute vec3 c; uniform mat4 mv; uniform mat4 pr; uniform vec3 off;" +
    "varying vec3 vc; varying float l;" +
    "void main() { vec4 q = mv * vec4(p + off, 1.0); gl_Position = pr * q;" +
    " vec3 m = normalize((mv * vec4(n, 0.0)).xyz); l = 0.3 + 0.7 * abs(m.z); vc = c; }"));
  gl.attachShader(prog, shader(gl.FRAGMENT_SHADER,
    "precision mediump float; varying vec3 vc; varying float l; void main() { gl_FragColor = vec4(vc * l, 1.0); }"));
  gl.linkProgram(prog);
  if (!gl.getProgramParameter(prog, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(prog));
  gl.useProgram(prog);
  var loc = {p: gl.getAttribLocation(prog, "p"), n: gl.getAttribLocation(prog, "n"), c: gl.getAttribLocation(prog, "c"),
             mv: gl.getUniformLocation(prog, "mv"), pr: gl.getUniformLocation(prog, "pr"),
             off: gl.getUniformLocation(prog, "off")};
  var meshes = layers.map(function (L) {
    var v = new Float32Array(bytes(L.verts)), c = new Uint8Array(bytes(L.colors));
    var f = L.index32 ? new Uint32Array(bytes(L.faces)) : new Uint16Array(bytes(L.faces));
    var nv = new Float32Array(v.length), lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (var t = 0; t < f.length; t += 3) {
      var a = 3 * f[t], b = 3 * f[t + 1], d = 3 * f[t + 2];
      var ux = v[b] - v[a], uy = v[b + 1] - v[a + 1], uz = v[b + 2] - v[a + 2];
      var wx = v[d] - v[a], wy = v[d + 1] - v[a + 1], wz = v[d + 2] - v[a + 2];
      var nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
      [a, b, d].forEach(function (k) { nv[k] += nx; nv[k + 1] += ny; nv[k + 2] += nz; });
    }
    for (var i = 0; i < v.length; i++) { lo[i % 3] = Math.min(lo[i % 3], v[i]); hi[i % 3] = Math.max(hi[i % 3], v[i]); }
    function buffer(target, data) { var b = gl.createBuffer(); gl.bindBuffer(target, b); gl.bufferData(target, data, gl.STATIC_DRAW); return b; }
    return {p: buffer(gl.ARRAY_BUFFER, v), n: buffer(gl.ARRAY_BUFFER, nv), c: buffer(gl.ARRAY_BUFFER, c),
            f: buffer(gl.ELEMENT_ARRAY_BUFFER, f), count: f.length, index32: L.index32, lo: lo, hi: hi, shown: true};
  });
  var yaw = 0, pitch = 0, zoom = 1;
  function mul(a, b) {
    var o = new Float32Array(16);
    for (var i = 0; i < 4; i++) for (var j = 0; j < 4; j++) {
      var s = 0; for (var k = 0; k < 4; k++) s += a[k * 4 + j] * b[i * 4 + k]; o[i * 4 + j] = s;
    }
    return o;
  }
  function draw() {
    var shown = meshes.filter(function (m) { return m.shown && (wide || !m.index32); });
    var width = 0, height = 0, depth = 0, gap = 0;
    shown.forEach(function (m) { gap = Math.max(gap, 0.1 * (m.hi[0] - m.lo[0])); });
    shown.forEach(function (m) { width += m.hi[0] - m.lo[0]; height = Math.max(height, m.hi[1] - m.lo[1]);
                                 depth = Math.max(depth, m.hi[2] - m.lo[2]); });
    width += gap * Math.max(shown.length - 1, 0);
    var radius = 0.5 * Math.sqrt(width * width + height * height + depth * depth) || 1;
    var dist = 1.6 * radius / zoom, aspect = canvas.width / canvas.height, fov = 1 / Math.tan(Math.PI / 8);
    var near = Math.max(dist - 2 * radius, dist * 0.01), far = dist + 2 * radius;
    var pr = new Float32Array([fov / aspect, 0, 0, 0, 0, fov, 0, 0, 0, 0, (far + near) / (near - far), -1,
                               0, 0, 2 * far * near / (near - far), 0]);
    var cy = Math.cos(yaw), sy = Math.sin(yaw), cp = Math.cos(pitch), sp = Math.sin(pitch);
    var rot = mul(new Float32Array([1, 0, 0, 0, 0, cp, sp, 0, 0, -sp, cp, 0, 0, 0, 0, 1]),
                  new Float32Array([cy, 0, -sy, 0, 0, 1, 0, 0, sy, 0, cy, 0, 0, 0, 0, 1]));
    var mv = mul(new Float32Array([1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -dist, 1]), rot);
    gl.viewport(0, 0, canvas.width, canvas.height);
    gl.clearColor(0.98, 0.98, 0.98, 1); gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    gl.enable(gl.DEPTH_TEST);
    gl.uniformMatrix4fv(loc.mv, false, mv); gl.uniformMatrix4fv(loc.pr, false, pr);
    var x = -0.5 * width;
    shown.forEach(function (m) {
      var off = [x - m.lo[0], -0.5 * (m.lo[1] + m.hi[1]), -0.5 * (m.lo[2] + m.hi[2])];
      x += m.hi[0] - m.lo[0] + gap;
      gl.uniform3fv(loc.off, off);
      [["p", m.p, gl.FLOAT, false], ["n", m.n, gl.FLOAT, false], ["c", m.c, gl.UNSIGNED_BYTE, true]].forEach(function (a) {
        gl.bindBuffer(gl.ARRAY_BUFFER, a[1]); gl.enableVertexAttribArray(loc[a[0]]);
        gl.vertexAttribPointer(loc[a[0]], 3, a[2], a[3], 0, 0);
      });
      gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, m.f);
      gl.drawElements(gl.TRIANGLES, m.count, m.index32 ? gl.UNSIGNED_INT : gl.UNSIGNED_SHORT, 0);
    });
  }
  var drag = null;
  canvas.addEventListener("mousedown", function (e) { drag = [e.clientX, e.clientY]; });
  window.addEventListener("mouseup", function () { drag = null; });
  window.addEventListener("mousemove", function (e) {
    if (!drag) return;
    yaw += 0.01 * (e.clientX - drag[0]); pitch += 0.01 * (e.clientY - drag[1]);
    pitch = Math.max(-1.55, Math.min(1.55, pitch)); drag = [e.clientX, e.clientY]; draw();
  });
  canvas.addEventListener("wheel", function (e) {
    e.preventDefault(); zoom = Math.max(0.2, Math.min(20, zoom * Math.exp(-0.001 * e.deltaY))); draw();
  }, {passive: false});
  canvas.addEventListener("dblclick", function () { yaw = 0; pitch = 0; zoom = 1; draw(); });
  document.querySelectorAll("input[data-layer]").forEach(function (box) {
    box.addEventListener("change", function () { meshes[+box.dataset.layer].shown = box.checked; draw(); });
  });
  draw();
})();
