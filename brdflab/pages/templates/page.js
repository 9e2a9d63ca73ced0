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
  window.addEventListener('load', () => {
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
      flippable: flips.length, flipped: flipped, restored: restored});
  });
})();
