// dttmm report: tables that fit their column (words break where a table would be too wide),
// sortable tables (click a header), "show all rows", video play/pause below the drawing.
const fit = () => document.querySelectorAll('table.t').forEach(t => {
  if (t.scrollWidth > t.parentElement.clientWidth + 1) t.classList.add('dense');
});
fit();
window.addEventListener('resize', fit);
document.querySelectorAll('table.t').forEach(t => {
  t.querySelectorAll('th').forEach((th, col) => {
    th.title = 'sort';
    th.addEventListener('click', () => {
      const body = t.tBodies[0], rows = [...body.rows];
      const up = th.dataset.dir !== 'up';
      t.querySelectorAll('th').forEach(x => delete x.dataset.dir);
      th.dataset.dir = up ? 'up' : 'down';
      const key = r => { const c = r.cells[col]; return c.dataset.v !== undefined ? +c.dataset.v : c.textContent; };
      rows.sort((a, b) => {
        const x = key(a), y = key(b);
        const r = (typeof x === 'number' && typeof y === 'number') ? x - y
          : (typeof x === 'number') ? -1 : (typeof y === 'number') ? 1 : String(x).localeCompare(String(y));
        return up ? r : -r;
      });
      rows.forEach(r => body.appendChild(r));
    });
  });
});
document.querySelectorAll('button.all').forEach(b => b.addEventListener('click', () => {
  const t = document.getElementById(b.dataset.table);
  const open = t.classList.toggle('open');
  b.textContent = open ? 'show fewer rows' : b.dataset.label;
  fit();
}));
document.querySelectorAll('button.all').forEach(b => { b.dataset.label = b.textContent; });
document.querySelectorAll('button.play').forEach(b => b.addEventListener('click', () => {
  const v = document.getElementById(b.dataset.video);
  if (v.paused) { v.play(); b.textContent = 'pause'; } else { v.pause(); b.textContent = 'play'; }
}));
