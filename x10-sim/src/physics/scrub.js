// The top view's slider (x10-sim/src/physics/view.rs): moves the robot along its recorded path
// and a time cursor across the timeline's lanes; beams after the chosen instant are hidden.
(function () {
  var arena = document.getElementById('x10-arena');
  var slider = document.getElementById('x10-scrub');
  var robot = document.getElementById('x10-robot');
  if (!arena || !slider || !robot) return;
  var path = arena.getAttribute('data-path').split(';').filter(function (s) { return s; })
    .map(function (s) { return s.split(',').map(Number); });
  var label = document.getElementById('x10-scrub-t');
  var tl = document.getElementById('x10-timeline');
  var cursor = null;
  if (tl) {
    cursor = document.createElementNS(tl.namespaceURI, 'line');
    cursor.setAttribute('y1', 0);
    cursor.setAttribute('y2', tl.getAttribute('height'));
    cursor.setAttribute('stroke', '#0969da');
    cursor.setAttribute('stroke-width', '1');
    tl.appendChild(cursor);
  }
  function show() {
    var p = path[Math.min(path.length - 1, +slider.value)];
    if (!p) return;
    robot.setAttribute('transform', 'translate(' + p[1] + ',' + p[2] + ') rotate(' + (-p[3]) + ')');
    if (label) label.textContent = p[0].toFixed(3) + ' s';
    arena.querySelectorAll('line.beam').forEach(function (b) {
      b.setAttribute('visibility', +b.getAttribute('data-t') <= p[0] ? 'visible' : 'hidden');
    });
    if (cursor && tl) {
      var L = +tl.getAttribute('data-left'), R = +tl.getAttribute('data-right');
      var end = +tl.getAttribute('data-end-s');
      var x = tl.x10px ? tl.x10px(p[0]) : L + (p[0] / end) * (R - L);
      cursor.setAttribute('x1', x);
      cursor.setAttribute('x2', x);
    }
  }
  slider.addEventListener('input', show);
  if (tl) tl.addEventListener('wheel', function () { setTimeout(show, 0); });
  show();
})();
