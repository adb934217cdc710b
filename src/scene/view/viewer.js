/* viewer.js: the page `crease view` writes (docs/view.md). Plays the panels of
 * CREASE_META side by side on one timeline, with one orbit camera for all.
 *
 * Data: each part (a garment or body of a panel) is one binary block:
 *   tri  uint32 (F,3)   triangles
 *   pos  uint16 (T,V,3) positions quantised over the part's box: lo + q * step
 *   val  uint8  (S,V)   optional scalar per vertex, quantised over the colour
 *                       bar's range (S = T, or 1 for a constant field)
 * at the byte offsets the meta gives. A block is embedded in the page as
 * base64 (<script type="application/octet-stream" id="crease-part-P-K">) or,
 * for large pages, lies in data/ beside it and is fetched (needs http:, so
 * `crease view --serve DIR`).
 *
 * URL hash: #frame=N shows frame N paused; #play starts playing; #bench=S plays
 * every frame for S seconds and logs the frames per second rendered. The page
 * logs "crease-view: ..." lines on the console (the test reads them) and sets
 * document.body.dataset.status to "loading", "ready" or "error".
 *
 * Leaves out: textures, per-face colours, several cameras. */
(function () {
  'use strict';
  const meta = JSON.parse(document.getElementById('crease-meta').textContent);
  const view = document.getElementById('view');
  const bar = document.getElementById('bar');
  const el = (id) => document.getElementById(id);
  document.body.dataset.status = 'loading';

  function fail(msg) {
    document.body.dataset.status = 'error';
    el('message').textContent = msg;
    el('message').style.display = 'block';
    console.log('crease-view: error: ' + msg);
  }

  /* ---- data --------------------------------------------------------------- */
  function decodeBase64(text) {
    const s = atob(text.replace(/\s+/g, ''));
    const out = new Uint8Array(s.length);
    for (let i = 0; i < s.length; i++) out[i] = s.charCodeAt(i);
    return out.buffer;
  }

  function loadPart(p, k, part) {
    if (!part.file) {
      const node = document.getElementById('crease-part-' + p + '-' + k);
      return Promise.resolve(decodeBase64(node.textContent));
    }
    if (location.protocol === 'file:')
      return Promise.reject(new Error('this page keeps its sequences in data/ beside it; ' +
                                      'serve it with: crease view --serve DIR'));
    return fetch(part.file).then((r) => {
      if (!r.ok) throw new Error(part.file + ': HTTP ' + r.status);
      return r.arrayBuffer();
    });
  }

  /* ---- colours ------------------------------------------------------------ */
  /* Viridis at 9 stops (matplotlib's _viridis_data), linearly interpolated. */
  const VIRIDIS = [[68, 1, 84], [71, 44, 122], [59, 81, 139], [44, 113, 142], [33, 144, 141],
                   [39, 173, 129], [92, 200, 99], [170, 220, 50], [253, 231, 37]];
  const LUT = new Float32Array(256 * 3);
  for (let i = 0; i < 256; i++) {
    const x = i / 255 * (VIRIDIS.length - 1), j = Math.min(Math.floor(x), VIRIDIS.length - 2);
    const f = x - j;
    for (let c = 0; c < 3; c++)
      LUT[3 * i + c] = ((1 - f) * VIRIDIS[j][c] + f * VIRIDIS[j + 1][c]) / 255;
  }
  const COLORS = {garment: 0x4f8fd0, body: 0xc8b8a8, object: 0xb0b0b0};

  /* ---- scene -------------------------------------------------------------- */
  /* Multisampling costs software GL (SwiftShader, llvmpipe) 3x the frame time
   * (docs/view.md), so it is on only for a hardware renderer; #aa=0 / #aa=1 force it. */
  function softwareGL() {
    const gl = document.createElement('canvas').getContext('webgl');
    const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
    const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
    const lose = gl && gl.getExtension('WEBGL_lose_context');
    if (lose) lose.loseContext();
    return /swiftshader|llvmpipe|software/i.test(name);
  }
  const aaHash = /(?:^#|&)aa=([01])/.exec(location.hash);
  const antialias = aaHash ? aaHash[1] === '1' : !softwareGL();
  const renderer = new THREE.WebGLRenderer({antialias: antialias, preserveDrawingBuffer: true});
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setScissorTest(true);
  view.appendChild(renderer.domElement);
  const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 100);
  const controls = new THREE.OrbitControls(camera, renderer.domElement);
  controls.enableKeys = false; /* the arrow keys step frames */

  const panels = meta.panels.map((pm, p) => {
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xf4f4f2);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x606068, 0.75));
    const sun = new THREE.DirectionalLight(0xffffff, 0.55);
    sun.position.set(1.5, 3, 2);
    scene.add(sun);
    const label = document.createElement('div');
    label.className = 'label';
    label.textContent = pm.label;
    view.appendChild(label);
    return {meta: pm, scene: scene, label: label, parts: [], index: p};
  });

  function buildPart(panel, pm, buf) {
    const nv = pm.vertices, nf = pm.faces;
    const geo = new THREE.BufferGeometry();
    geo.setIndex(new THREE.BufferAttribute(new Uint32Array(buf, pm.tri_offset, nf * 3), 1));
    const pos = new THREE.BufferAttribute(new Float32Array(nv * 3), 3);
    pos.setUsage ? pos.setUsage(THREE.DynamicDrawUsage) : (pos.dynamic = true);
    geo.setAttribute('position', pos);
    const mat = new THREE.MeshPhongMaterial({
      color: pm.scalar ? 0xffffff : COLORS[pm.role] || COLORS.object,
      side: THREE.DoubleSide, shininess: 12, vertexColors: pm.scalar ? THREE.VertexColors : 0,
      /* a body a few millimetres under the garment would show through it (z-fighting) */
      polygonOffset: pm.role === 'body', polygonOffsetFactor: 2, polygonOffsetUnits: 2,
    });
    let col = null;
    if (pm.scalar) {
      col = new THREE.BufferAttribute(new Float32Array(nv * 3), 3);
      geo.setAttribute('color', col);
    }
    const mesh = new THREE.Mesh(geo, mat);
    mesh.frustumCulled = false;
    panel.scene.add(mesh);
    const part = {
      meta: pm, geo: geo, mesh: mesh, pos: pos, col: col, shown: -1,
      q: new Uint16Array(buf, pm.pos_offset, pm.frames * nv * 3),
      val: pm.scalar ? new Uint8Array(buf, pm.scalar.offset, pm.scalar.frames * nv) : null,
    };
    panel.parts.push(part);
  }

  function showPart(part, frame) {
    const pm = part.meta, f = Math.min(frame, pm.frames - 1);
    if (part.shown === f) return;
    part.shown = f;
    const nv = pm.vertices, a = part.pos.array, q = part.q, o = f * nv * 3;
    const lo = pm.lo, st = pm.step;
    for (let i = 0; i < nv; i++) {
      const j = 3 * i;
      a[j] = lo[0] + q[o + j] * st[0];
      a[j + 1] = lo[1] + q[o + j + 1] * st[1];
      a[j + 2] = lo[2] + q[o + j + 2] * st[2];
    }
    part.pos.needsUpdate = true;
    part.geo.computeVertexNormals();
    if (part.col) {
      const c = part.col.array, v = part.val, vo = Math.min(f, pm.scalar.frames - 1) * nv;
      for (let i = 0; i < nv; i++) {
        const l = 3 * v[vo + i];
        c[3 * i] = LUT[l];
        c[3 * i + 1] = LUT[l + 1];
        c[3 * i + 2] = LUT[l + 2];
      }
      part.col.needsUpdate = true;
    }
  }

  /* ---- layout and drawing ------------------------------------------------- */
  const cols = Math.min(panels.length, meta.columns || 4), rows = Math.ceil(panels.length / cols);
  let pw = 1, ph = 1;
  function layout() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = w + 'px';
    renderer.domElement.style.height = h + 'px';
    pw = Math.floor(w / cols);
    ph = Math.floor(h / rows);
    camera.aspect = pw / ph;
    camera.updateProjectionMatrix();
    panels.forEach((p, i) => {
      p.x = (i % cols) * pw;
      p.y = Math.floor(i / cols) * ph;
      p.label.style.left = (p.x + 8) + 'px';
      p.label.style.top = (p.y + 6) + 'px';
    });
  }

  let frame = 0;
  function draw() {
    const h = view.clientHeight;
    const t0 = performance.now();
    for (const p of panels)
      for (const part of p.parts) showPart(part, frame);
    const t1 = performance.now();
    for (const p of panels) {
      renderer.setViewport(p.x, h - p.y - ph, pw, ph);
      renderer.setScissor(p.x, h - p.y - ph, pw, ph);
      renderer.render(p.scene, camera);
    }
    if (bench) {
      bench.update += t1 - t0;
      bench.render += performance.now() - t1;
    }
    const t = frame / meta.fps;
    el('frame').textContent = 'frame ' + frame + ' / ' + (meta.frames - 1) + '   ' +
                              t.toFixed(3) + ' s';
    el('scrub').value = frame;
  }

  /* ---- timeline ----------------------------------------------------------- */
  let playing = false, clock0 = 0, frame0 = 0, needDraw = true, bench = null;
  function setFrame(f) {
    frame = Math.max(0, Math.min(meta.frames - 1, f | 0));
    needDraw = true;
  }
  function play(on) {
    playing = on && meta.frames > 1;
    if (playing && frame >= meta.frames - 1 && !el('loop').checked) setFrame(0);
    clock0 = performance.now();
    frame0 = frame;
    el('play').textContent = playing ? 'pause' : 'play';
  }
  function speed() { return parseFloat(el('speed').value) || 1; }
  function tick(now) {
    if (bench) {
      bench.n++;
      setFrame((frame + 1) % meta.frames);
      if (now - bench.t0 >= bench.seconds * 1000) {
        const fps = bench.n / ((now - bench.t0) / 1000);
        console.log('crease-view: bench fps=' + fps.toFixed(1) + ' frames=' + bench.n +
                    ' sequence_fps=' + meta.fps + ' update_ms=' + (bench.update / bench.n).toFixed(1) +
                    ' render_ms=' + (bench.render / bench.n).toFixed(1) + ' size=' +
                    view.clientWidth + 'x' + view.clientHeight + ' antialias=' + antialias);
        document.body.dataset.benchFps = fps.toFixed(1);
        bench = null;
      }
    } else if (playing) {
      let f = frame0 + Math.floor((now - clock0) / 1000 * meta.fps * speed());
      if (f >= meta.frames) {
        if (el('loop').checked) {
          f %= meta.frames;
        } else {
          f = meta.frames - 1;
          play(false);
        }
      }
      if (f !== frame) setFrame(f);
    }
    if (needDraw) {
      needDraw = false;
      draw();
    }
    requestAnimationFrame(tick);
  }

  function readHash() {
    const h = location.hash.replace(/^#/, '');
    for (const kv of h.split('&')) {
      const [k, v] = kv.split('=');
      if (k === 'frame') {
        play(false);
        setFrame(parseInt(v, 10) || 0);
      } else if (k === 'play') {
        play(true);
      } else if (k === 'bench') {
        bench = {seconds: parseFloat(v) || 3, n: 0, t0: performance.now(), update: 0, render: 0};
      } else if (k === 'wire') {
        el('wire').checked = v !== '0';
        wire();
      }
    }
  }

  function wire() {
    for (const p of panels)
      for (const part of p.parts) part.mesh.material.wireframe = el('wire').checked;
    needDraw = true;
  }

  function colorbar() {
    const cb = meta.colorbar;
    if (!cb) return;
    el('colorbar').style.display = 'flex';
    const c = el('cbar'), g = c.getContext('2d'), img = g.createImageData(256, 1);
    for (let i = 0; i < 256; i++)
      for (let k = 0; k < 3; k++) img.data[4 * i + k] = Math.round(255 * LUT[3 * i + k]);
    for (let i = 0; i < 256; i++) img.data[4 * i + 3] = 255;
    g.putImageData(img, 0, 0);
    el('cb-lo').textContent = cb.lo.toPrecision(3);
    el('cb-hi').textContent = cb.hi.toPrecision(3) + (cb.unit ? ' ' + cb.unit : '');
    el('cb-name').textContent = cb.name;
  }

  /* ---- start -------------------------------------------------------------- */
  const c = meta.center, r = meta.radius;
  controls.target.set(c[0], c[1], c[2]);
  camera.position.set(c[0], c[1] + 0.9 * r, c[2] + 2.6 * r);
  camera.near = r / 100;
  camera.far = r * 100;
  controls.update();
  controls.addEventListener('change', () => { needDraw = true; });
  el('scrub').max = meta.frames - 1;
  el('play').onclick = () => play(!playing);
  el('back').onclick = () => { play(false); setFrame(frame - 1); };
  el('fwd').onclick = () => { play(false); setFrame(frame + 1); };
  el('scrub').oninput = () => { play(false); setFrame(parseInt(el('scrub').value, 10)); };
  el('speed').onchange = () => play(playing);
  el('wire').onchange = wire;
  document.addEventListener('keydown', (e) => {
    if (e.target.tagName === 'SELECT') return;
    if (e.key === ' ') { play(!playing); e.preventDefault(); }
    else if (e.key === 'ArrowRight') { play(false); setFrame(frame + 1); }
    else if (e.key === 'ArrowLeft') { play(false); setFrame(frame - 1); }
    else if (e.key === 'w') { el('wire').checked = !el('wire').checked; wire(); }
  });
  window.addEventListener('resize', () => { layout(); needDraw = true; });
  window.addEventListener('hashchange', readHash);
  colorbar();
  layout();

  const jobs = [];
  let loaded = 0, nparts = 0;
  meta.panels.forEach((pm) => { nparts += pm.parts.length; });
  meta.panels.forEach((pm, p) => pm.parts.forEach((part, k) => {
    jobs.push(loadPart(p, k, part).then((buf) => {
      buildPart(panels[p], part, buf);
      el('loaded').textContent = 'loaded ' + (++loaded) + ' of ' + nparts + ' parts';
    }));
  }));
  Promise.all(jobs).then(() => {
    for (const p of panels) p.parts.sort((a, b) => meta.panels[p.index].parts.indexOf(a.meta) -
                                                   meta.panels[p.index].parts.indexOf(b.meta));
    readHash();
    draw(); /* synchronously, so a screenshot taken at load sees the frame */
    document.body.dataset.status = 'ready';
    document.title = 'crease view: ready';
    el('loaded').textContent = panels.length + (panels.length > 1 ? ' panels' : ' panel');
    console.log('crease-view: ready panels=' + panels.length + ' frames=' + meta.frames +
                ' frame=' + frame);
    requestAnimationFrame(tick);
  }).catch((e) => fail(e.message || String(e)));
})();
