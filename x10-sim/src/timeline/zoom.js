// Horizontal zoom and pan of the X10 timeline (x10-sim/src/timeline/plot.rs): no network, no
// external asset. A base x (the whole run) maps to L + (x - L) * k + off.
(function () {
  var svg = document.getElementById('x10-timeline');
  if (!svg) return;
  var num = function (e, a) { return +e.getAttribute(a); };
  var L = num(svg, 'data-left'), R = num(svg, 'data-right'), end = num(svg, 'data-end-s');
  var ROW = num(svg, 'data-row'), SPACE = num(svg, 'data-space');
  if (!(end > 0)) return;
  var W = R - L, k = 1, off = 0, NS = svg.namespaceURI;
  var px = function (x) { return L + (x - L) * k + off; };
  // The x of instant t_s at the current zoom (the arena's slider draws its cursor with it).
  svg.x10px = function (t) { return px(L + (t / end) * W); };

  // Labels: the first row with room, as plot.rs places them; the lane says how many had none.
  function layout() {
    svg.querySelectorAll('g.labels').forEach(function (g) {
      var rows = num(g, 'data-rows'), y = num(g, 'data-y'), ends = [], hidden = 0;
      for (var i = 0; i < rows; i++) ends.push(-Infinity);
      g.querySelectorAll('text.label').forEach(function (t) {
        var x = px(num(t, 'data-x')), w = num(t, 'data-w'), a, b, anchor;
        // A change scrolled out of the plot has no label; one whose text would cross an edge
        // of the plot (over the lanes' names, past the right end) has no room.
        if (x < L || x > R) { t.setAttribute('visibility', 'hidden'); return; }
        if (x + 2 + w <= R) { a = x + 2; b = a + w; anchor = 'start'; } else { b = x - 2; a = b - w; anchor = 'end'; }
        if (a < L) { hidden++; t.setAttribute('visibility', 'hidden'); return; }
        var r = 0;
        while (r < rows && ends[r] + SPACE > a) r++;
        if (r === rows) { hidden++; t.setAttribute('visibility', 'hidden'); return; }
        ends[r] = b;
        t.setAttribute('x', (anchor === 'start' ? a : b).toFixed(1));
        t.setAttribute('y', (y + r * ROW).toFixed(1));
        t.setAttribute('text-anchor', anchor);
        t.removeAttribute('visibility');
      });
      var note = document.getElementById(g.getAttribute('data-note'));
      if (note) {
        note.textContent = hidden === 0 ? '' : hidden + (hidden === 1 ? ' label' : ' labels') + ' without room: zoom in or hover';
      }
    });
  }

  function line(g, x1, y1, x2, y2, stroke, dash) {
    var l = document.createElementNS(NS, 'line');
    l.setAttribute('x1', x1); l.setAttribute('y1', y1); l.setAttribute('x2', x2); l.setAttribute('y2', y2);
    l.setAttribute('stroke', stroke);
    if (dash) l.setAttribute('stroke-dasharray', dash);
    g.appendChild(l);
  }

  // Ticks at 1, 2 or 5 times a power of ten, at most 10 across the visible part.
  function ticks() {
    var g = document.getElementById('x10-ticks');
    var top = num(g, 'data-top'), ay = num(g, 'data-axis');
    while (g.firstChild) g.removeChild(g.firstChild);
    var t0 = -off / (W * k) * end, t1 = (W - off) / (W * k) * end, step = 1e-6, found = false;
    while (!found) {
      for (var m of [1, 2, 5]) {
        if ((t1 - t0) / (step * m) <= 10) { step *= m; found = true; break; }
      }
      if (!found) step *= 10;
    }
    var decimals = Math.max(0, Math.ceil(-Math.log10(step) - 1e-9));
    for (var i = Math.ceil(t0 / step - 1e-6); i * step <= t1 + step * 1e-6; i++) {
      var t = i * step, x = (L + (t / end) * W * k + off).toFixed(1);
      line(g, x, top, x, ay, '#d0d7de', '2,3');
      line(g, x, ay, x, ay + 5, '#57606a');
      var text = document.createElementNS(NS, 'text'), s = t.toFixed(decimals);
      if (s.indexOf('.') >= 0) s = s.replace(/0+$/, '').replace(/\.$/, '');
      text.setAttribute('x', x); text.setAttribute('y', ay + 18);
      text.setAttribute('font-size', 11); text.setAttribute('fill', '#24292f');
      text.setAttribute('text-anchor', +x < L + 20 ? 'start' : +x > R - 20 ? 'end' : 'middle');
      text.textContent = s + ' s';
      g.appendChild(text);
    }
  }

  function apply() {
    off = Math.min(0, Math.max(W - W * k, off));
    var tf = 'translate(' + (L + off) + ' 0) scale(' + k + ' 1) translate(' + (-L) + ' 0)';
    svg.querySelectorAll('g.zoom').forEach(function (g) { g.setAttribute('transform', tf); });
    svg.querySelectorAll('circle[data-x]').forEach(function (c) { c.setAttribute('cx', px(num(c, 'data-x')).toFixed(1)); });
    layout();
    ticks();
    var z = document.getElementById('x10-zoom');
    if (z) z.textContent = (k < 10 ? k.toFixed(1) : k.toFixed(0)) + '×';
  }

  function zoomAt(x, f) {
    var base = L + (x - L - off) / k;
    k = Math.min(1e6, Math.max(1, k * f));
    off = x - L - (base - L) * k;
    apply();
  }

  function svgX(e) {
    var p = svg.createSVGPoint();
    p.x = e.clientX; p.y = e.clientY;
    return p.matrixTransform(svg.getScreenCTM().inverse()).x;
  }

  svg.addEventListener('wheel', function (e) {
    var x = svgX(e);
    if (x < L || x > R) return;
    e.preventDefault();
    zoomAt(x, e.deltaY < 0 ? 1.25 : 0.8);
  }, { passive: false });
  var drag = null;
  svg.addEventListener('pointerdown', function (e) { drag = svgX(e); });
  svg.addEventListener('pointermove', function (e) {
    if (drag === null) return;
    var x = svgX(e);
    off += x - drag; drag = x; apply();
  });
  window.addEventListener('pointerup', function () { drag = null; });
  var button = function (id, f) { var b = document.getElementById(id); if (b) b.addEventListener('click', f); };
  button('x10-in', function () { zoomAt(L + W / 2, 2); });
  button('x10-out', function () { zoomAt(L + W / 2, 0.5); });
  button('x10-reset', function () { k = 1; off = 0; apply(); });
  document.addEventListener('keydown', function (e) {
    if (e.key === '+' || e.key === '=') zoomAt(L + W / 2, 2);
    else if (e.key === '-') zoomAt(L + W / 2, 0.5);
    else if (e.key === 'ArrowLeft') { off += W / 4; apply(); }
    else if (e.key === 'ArrowRight') { off -= W / 4; apply(); }
  });
  // A view to open with: page.html#t=1.0-1.5 shows 1.0 s to 1.5 s.
  var m = /^#t=([0-9.]+)-([0-9.]+)$/.exec(location.hash);
  if (m && +m[2] > +m[1] && end > 0) {
    k = Math.min(1e6, end / (+m[2] - +m[1]));
    off = -(+m[1] / end) * W * k;
  }
  apply();
})();
