(function(){
  const imgs = () => Array.from(document.querySelectorAll('img.render'));
  function zoomAll(x, y, on){
    imgs().forEach(o => {
      o.style.transformOrigin = (100*x) + '% ' + (100*y) + '%';
      o.style.transform = on ? 'scale(4)' : '';
      o.classList.toggle('zoomed', on);
    });
  }
  // A/B flip against the reference (tev style): swap the image source in place, keeping the zoom.
  function setFlip(img, on){
    const ref = document.getElementById(img.dataset.ref || '');
    if (!ref) return;
    if (!img.dataset.own) img.dataset.own = img.src;
    img.src = on ? ref.src : img.dataset.own;
    img.classList.toggle('flipped', on);
    const b = img.parentElement.querySelector('button.flip');
    if (b) { b.classList.toggle('on', on); b.textContent = on ? 'B: reference' : 'A/B'; }
  }
  const flippable = () => imgs().filter(o => o.dataset.ref);
  document.addEventListener('click', e => {
    const b = e.target.closest('button.flip');
    if (b) {
      e.stopPropagation();
      const img = b.parentElement.querySelector('img.render');
      setFlip(img, !img.classList.contains('flipped'));
      return;
    }
    const img = e.target.closest('img.render');
    if (!img) return;
    const r = img.getBoundingClientRect();
    const x = (e.clientX - r.left) / r.width, y = (e.clientY - r.top) / r.height;
    zoomAll(x, y, !img.classList.contains('zoomed'));
  });
  document.addEventListener('keydown', e => {
    if (e.key !== 'r' && e.key !== 'R') return;
    const all = flippable();
    const on = !all.some(o => o.classList.contains('flipped'));
    all.forEach(o => setFlip(o, on));
  });
  // tev-style display controls for the renders: an exposure slider (the preview PNGs are sRGB; the exposure is
  // applied to their linearised values, then re-encoded) and a pixel read-out of every render of the row under
  // the cursor (linearised from the 8-bit preview: values above 1 read as 1; the EXR files hold the exact ones).
  const lin = c => { c /= 255; return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4); };
  const canvases = new WeakMap();
  function pixelOf(img, x, y){
    let cv = canvases.get(img);
    if (!cv) {
      cv = document.createElement('canvas');
      cv.width = img.naturalWidth; cv.height = img.naturalHeight;
      try { cv.getContext('2d').drawImage(img, 0, 0); } catch (err) { return null; }
      canvases.set(img, cv);
    }
    const d = cv.getContext('2d').getImageData(x, y, 1, 1).data;
    return [lin(d[0]), lin(d[1]), lin(d[2])];
  }
  let readout = null, ev = 0;
  function setExposure(v){
    ev = v;
    const k = Math.pow(2, v);  // sRGB ≈ linear^(1/2.2): a linear gain k is a gain k^(1/2.2) on the preview
    imgs().forEach(o => { o.style.filter = v ? 'brightness(' + Math.pow(k, 1 / 2.2).toFixed(4) + ')' : ''; });
    const label = document.getElementById('ev-label');
    if (label) label.textContent = (v >= 0 ? '+' : '') + v.toFixed(1) + ' EV';
  }
  function toolbar(){
    if (!imgs().length || document.getElementById('ev')) return;
    const bar = document.createElement('div');
    bar.className = 'toolbar';
    bar.innerHTML = '<label>exposure <input id="ev" type="range" min="-6" max="6" step="0.5" value="0"> ' +
      '<span id="ev-label">+0.0 EV</span></label> <span class="hint">click: zoom ×4 · R: A/B all · ' +
      'hover: pixel values</span>';
    document.querySelector('main').prepend(bar);
    bar.querySelector('#ev').addEventListener('input', e => setExposure(parseFloat(e.target.value)));
    readout = document.createElement('div');
    readout.className = 'readout';
    readout.hidden = true;
    document.body.appendChild(readout);
  }
  document.addEventListener('mousemove', e => {
    const img = e.target.closest && e.target.closest('img.render');
    if (!readout) return;
    if (!img || !img.naturalWidth) { readout.hidden = true; return; }
    const r = img.getBoundingClientRect();
    const x = Math.min(img.naturalWidth - 1, Math.floor((e.clientX - r.left) / r.width * img.naturalWidth));
    const y = Math.min(img.naturalHeight - 1, Math.floor((e.clientY - r.top) / r.height * img.naturalHeight));
    const row = img.closest('.row') || document;
    const lines = Array.from(row.querySelectorAll('img.render')).map(o => {
      const v = pixelOf(o, x, y);
      const cap = o.closest('figure') && o.closest('figure').querySelector('figcaption');
      return (cap ? cap.textContent.slice(0, 40) : 'image') + ': ' +
        (v ? v.map(c => c.toFixed(4)).join(', ') : 'n/a');
    });
    readout.textContent = 'x ' + x + ', y ' + y + '\n' + lines.join('\n');
    readout.style.left = (e.pageX + 14) + 'px';
    readout.style.top = (e.pageY + 14) + 'px';
    readout.hidden = false;
  });
  window.brdflabReadout = (img, x, y) => pixelOf(img, x, y);
  document.addEventListener('DOMContentLoaded', toolbar);
  window.addEventListener('load', () => {
    toolbar();
    if (location.hash !== '#selftest') return;
    const all = imgs();
    const first = all[0];
    if (first) {
      const r = first.getBoundingClientRect();
      first.dispatchEvent(new MouseEvent('click', {bubbles: true, clientX: r.left + r.width * 0.25,
                                                   clientY: r.top + r.height * 0.25}));
    }
    const flips = flippable();
    let flipped = 0, restored = 0;
    flips.forEach(o => {
      const own = o.src;
      o.parentElement.querySelector('button.flip').click();
      const ref = document.getElementById(o.dataset.ref);
      if (o.src === ref.src && o.src !== own) flipped++;
      o.parentElement.querySelector('button.flip').click();
      if (o.src === own) restored++;
    });
    const loaded = Array.from(document.images).filter(i => i.complete && i.naturalWidth > 0).length;
    document.body.dataset.selftest = JSON.stringify({
      images: document.images.length, loaded: loaded, renders: all.length,
      zoomed: all.filter(o => o.classList.contains('zoomed') && o.style.transform.includes('scale(4)')).length,
      plots: document.querySelectorAll('figure.plot img').length,
      flippable: flips.length, flipped: flipped, restored: restored,
      exposure: (() => { setExposure(2); const f = first ? first.style.filter : ''; setExposure(0);
                         return f.startsWith('brightness(') ? 1 : 0; })(),
      readout: (() => { const v = first ? pixelOf(first, 0, 0) : null;
                        return v && v.every(c => c >= 0 && c <= 1) ? 1 : 0; })()});
  });
})();
