"""The frame of every page: its style sheet and the player that moves each motion drawing."""

from __future__ import annotations

#: The style sheet of every page (a design's and the batch's index).
CSS = """
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",sans-serif;margin:0;color:#222;
background:#fafafa}
header{background:#263238;color:#fff;padding:14px 24px}header h1{margin:0;font-size:22px}
header p{margin:4px 0 0;color:#cfd8dc}main{padding:12px 24px;max-width:1200px}
h1,h2,h3,p,td,th,li,figcaption,summary{overflow-wrap:anywhere}
section{background:#fff;border:1px solid #ddd;border-radius:6px;padding:12px 16px;margin:12px 0}
h2{font-size:18px;margin:4px 0 10px}table{border-collapse:collapse;margin:6px 0;font-size:13px}
td,th{border:1px solid #ddd;padding:3px 8px;text-align:left;vertical-align:top}
th{background:#f0f0f0}.ok{color:#1b5e20;font-weight:600}.bad{color:#b71c1c;font-weight:600}
.warn{color:#e65100}.note{color:#5d4037;font-weight:600}.lead{border-left:5px solid #263238}
.strip i{display:inline-block;width:.7em;height:1.1em;margin-right:1px;border:1px solid;
vertical-align:middle}
.lead p{margin:4px 0}.verdict{border-left:5px solid #1b5e20}.verdict.FLAG,.verdict.FAIL{
border-left-color:#b71c1c}.verdict.by-design{border-left-color:#8d6e63}
.nowrap{white-space:nowrap}
.scroll{overflow-x:auto;max-width:100%}.pic{margin:8px 0}.pic img{max-width:none;display:block;
border:1px solid #eee}figcaption{font-size:13px;color:#555}
details{margin:8px 0}summary{cursor:pointer;font-weight:600}
.motion svg{width:100%;max-height:520px;background:#fff;border:1px solid #eee}
.controls{display:flex;gap:12px;align-items:center;margin:6px 0}
.controls input[type=range]{flex:1;min-width:0}.legend span{display:inline-block;margin-right:12px}
.legend i{display:inline-block;width:18px;height:4px;vertical-align:middle;margin-right:4px}
.grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(min(330px,100%),1fr));gap:12px}
.card{background:#fff;border:1px solid #ddd;border-radius:6px;padding:10px;min-width:0}
.card svg{width:100%;height:220px;background:#fff}.card h3{margin:0 0 4px;font-size:16px}
.inline-svg svg{max-width:none;height:auto}
"""


# One player for a page: every <svg data-motion="ID"> is bound to the frames in the JSON block
# with that id; a range input with data-for="ID" scrubs it, a button with data-play="ID" plays.
# Thumbnails (data-autoplay) loop on their own.
JS = """
(function(){
  function bind(svg){
    var data = JSON.parse(document.getElementById(svg.getAttribute('data-motion')).textContent);
    var ns = 'http://www.w3.org/2000/svg', lines = [], ports = [];
    var w = svg.getAttribute('data-width') || 1.5, polys = [];
    (data.faces || []).forEach(function(){
      var g = document.createElementNS(ns, 'polygon');
      g.setAttribute('fill', data.fill); g.setAttribute('fill-opacity', 0.7);
      g.setAttribute('stroke', 'none'); svg.appendChild(g); polys.push(g);
    });
    data.edges.forEach(function(e, k){
      var l = document.createElementNS(ns, 'line');
      l.setAttribute('stroke', data.colours[k]); l.setAttribute('stroke-width', w);
      l.setAttribute('stroke-linecap', 'round');
      l.setAttribute('vector-effect', 'non-scaling-stroke');
      svg.appendChild(l); lines.push(l);
    });
    data.ports.forEach(function(p){
      var l = document.createElementNS(ns, 'line');
      l.setAttribute('stroke', '#888'); l.setAttribute('stroke-width', 1);
      l.setAttribute('stroke-dasharray', '4 3');
      l.setAttribute('vector-effect', 'non-scaling-stroke');
      svg.insertBefore(l, svg.firstChild); ports.push(l);
    });
    function draw(f){
      var x = data.frames[f];
      (data.faces || []).forEach(function(face, k){
        polys[k].setAttribute('points', face.map(function(v){
          return x[v][0] + ',' + x[v][1]; }).join(' '));
      });
      data.edges.forEach(function(e, k){
        var l = lines[k];
        l.setAttribute('x1', x[e[0]][0]); l.setAttribute('y1', x[e[0]][1]);
        l.setAttribute('x2', x[e[1]][0]); l.setAttribute('y2', x[e[1]][1]);
      });
      data.ports.forEach(function(p, k){
        var l = ports[k];
        l.setAttribute('x1', x[p[1]][0]); l.setAttribute('y1', x[p[1]][1]);
        l.setAttribute('x2', x[p[2]][0]); l.setAttribute('y2', x[p[2]][1]);
      });
      svg.setAttribute('data-frame', f);
      var out = document.querySelector(
        '[data-value-for="' + svg.getAttribute('data-motion') + '"]');
      if (out) out.textContent = data.drive + ' = ' + data.values[f].toPrecision(6);
    }
    var id = svg.getAttribute('data-motion');
    var slider = document.querySelector('input[data-for="' + id + '"]');
    var button = document.querySelector('button[data-play="' + id + '"]');
    var timer = null, f = 0;
    function step(){ f = (f + 1) % data.frames.length; if (slider) slider.value = f; draw(f); }
    if (slider){ slider.max = data.frames.length - 1;
      slider.addEventListener('input', function(){ f = +slider.value; draw(f); }); }
    if (button) button.addEventListener('click', function(){
      if (timer){ clearInterval(timer); timer = null; button.textContent = 'play'; }
      else { timer = setInterval(step, 80); button.textContent = 'pause'; } });
    if (svg.hasAttribute('data-autoplay')) timer = setInterval(step, 90);
    draw(0);
  }
  document.querySelectorAll('svg[data-motion]').forEach(bind);
})();
"""
