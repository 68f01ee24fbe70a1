// The review page (marks.html) in headless Chromium, driven as a user would
// through puppeteer-core: the page loads offline (no request leaves it), the
// adjustment's w-test rejection shows, then one mark is dragged, one
// rejected, one placed where nothing was detected, one nudged with the
// keyboard, and both lists are downloaded into DIR/export/ (which
// `review_fixture check DIR` reads back with aerotri's reader).
// Usage: node check_review_page.mjs DIR   (DIR from `review_fixture write`;
// exit 77 = skipped: no Chromium, or puppeteer-core not installed by
// scripts/install-test-tools.sh into AEROTRI_NODE_MODULES)
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const dir = path.resolve(process.argv[2] || '.');
const chromium = process.env.CHROMIUM || ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find(p => fs.existsSync(p));
if (!chromium) {
  console.log('Chromium is not installed (scripts/install-test-tools.sh installs Debian\'s chromium): skipped');
  process.exit(77);
}
let puppeteer;
try {
  const require = createRequire((process.env.AEROTRI_NODE_MODULES || '.') + '/');
  puppeteer = require('puppeteer-core');
} catch (e) {
  console.log('puppeteer-core is not installed (scripts/install-test-tools.sh): skipped');
  process.exit(77);
}
const scenario = JSON.parse(fs.readFileSync(path.join(dir, 'scenario.json'), 'utf8'));
const exportDir = path.join(dir, 'export');
fs.rmSync(exportDir, { recursive: true, force: true });
fs.mkdirSync(exportDir);
const profile = fs.mkdtempSync(path.join(dir, 'profile-'));
let failures = 0;
const fail = (msg) => { console.log('FAIL: ' + msg); ++failures; };

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  userDataDir: profile,
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync'],
});
try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 1000, deviceScaleFactor: 1 });
  const errors = [], requests = [];
  page.on('pageerror', e => errors.push(String(e)));
  page.on('console', m => { if (m.type() === 'error') errors.push(m.text()); });
  page.on('request', r => { if (!/^(data|blob|file):/.test(r.url())) requests.push(r.url()); });
  const cdp = await page.createCDPSession();
  await cdp.send('Browser.setDownloadBehavior', { behavior: 'allow', downloadPath: exportDir });
  await page.goto('file://' + path.join(dir, 'marks.html'), { waitUntil: 'load' });

  const chipSel = (point, image) => `figure.chip[data-point="${point}"][data-image="${image}"]`;
  const chipState = (sel) => page.$eval(sel, f => ({
    state: f.dataset.state, verdict: f.querySelector('.verdict').textContent, detail: f.querySelector('.detail').textContent,
  }));
  // The photo point (x, y) in page CSS pixels (review_page.h's chip geometry).
  const toPage = async (point, image, xy) => {
    const view = await page.$(chipSel(point, image) + ' .view');
    await view.scrollIntoView();
    const box = await view.boundingBox();
    const c = await page.evaluate((p, im) => {
      const data = JSON.parse(document.getElementById('data').textContent);
      const photo = data.points.find(q => q.name === p).photos.find(q => q.image === im);
      return { ox: photo.ox, oy: photo.oy, scale: data.scale };
    }, point, image);
    return [box.x + (xy[0] - c.ox + 0.5) * c.scale, box.y + (xy[1] - c.oy + 0.5) * c.scale, c.scale];
  };
  const markOf = (point, image) => page.evaluate((p, im) => {
    const data = JSON.parse(document.getElementById('data').textContent);
    return data.points.find(q => q.name === p).photos.find(q => q.image === im).mark;
  }, point, image);

  // The page as written: every point, the statuses, the w-test's rejection.
  const sections = await page.$$eval('section.point', s => s.map(e => e.dataset.point));
  if (sections.join(',') !== 'GCP1,GCP2,GCP3,CHK1') fail('points on the page: ' + sections.join(','));
  const reason = await page.$eval('section.point[data-point="GCP3"] .reason', e => e.textContent);
  if (!reason.includes('no target within')) fail('GCP3 shows no reason: ' + reason);
  const ar = scenario.adjustment_rejected;
  const rejected = await chipState(chipSel(ar.point, ar.image));
  if (rejected.state !== 'rejected' || !rejected.verdict.includes('w-test')) {
    fail(`${ar.point} in ${ar.image}: the w-test's rejection is not shown (${JSON.stringify(rejected)})`);
  }
  const adjusted = await chipState(chipSel('GCP1', 'img_a.jpg'));
  if (!/residual after adjustment 0\.14 px, w 0\.4/.test(adjusted.detail)) fail('GCP1 img_a residual: ' + adjusted.detail);
  const before = await page.$eval('#summary', e => e.textContent);
  if (!before.startsWith('control: 2 points, 4 marks accepted; check points: 1 point, 2 marks accepted')) {
    fail('summary before editing: ' + before);
  }

  // Drag a mark by whole CSS pixels.
  const d = scenario.drag;
  const from = await markOf(d.point, d.image);
  const [x0, y0, scale] = await toPage(d.point, d.image, from);
  await page.mouse.move(x0, y0);
  await page.mouse.down();
  for (let s = 1; s <= 5; ++s) await page.mouse.move(x0 + d.by_px[0] * scale * s / 5, y0 + d.by_px[1] * scale * s / 5);
  await page.mouse.up();
  const dragged = await chipState(chipSel(d.point, d.image));
  if (dragged.state !== 'accepted' || !dragged.detail.includes('moved 3.61 px by hand')) {
    fail('after the drag: ' + JSON.stringify(dragged));
  }
  // Reject one.
  await page.click(chipSel(scenario.reject.point, scenario.reject.image) + ' button.reject');
  if ((await chipState(chipSel(scenario.reject.point, scenario.reject.image))).state !== 'rejected') fail('reject');
  // Place one where nothing was detected.
  const pl = scenario.place;
  const [px, py] = await toPage(pl.point, pl.image, pl.at_px);
  await page.mouse.click(px, py);
  const placed = await chipState(chipSel(pl.point, pl.image));
  if (placed.state !== 'accepted' || !placed.detail.includes('placed by hand')) fail('place: ' + JSON.stringify(placed));
  // Nudge one with the keyboard.
  const n = scenario.nudge;
  await page.focus(chipSel(n.point, n.image));
  for (const key of n.keys) {
    const [mod, k] = key.includes('+') ? key.split('+') : [null, key];
    if (mod) await page.keyboard.down(mod);
    await page.keyboard.press(k);
    if (mod) await page.keyboard.up(mod);
  }
  const after = await page.$eval('#summary', e => e.textContent);
  if (!after.startsWith('control: 3 points, 4 marks accepted; check points: 1 point, 2 marks accepted')) {
    fail('summary after editing: ' + after);
  }

  // Export both lists.
  for (const [button, file] of [['#export-control', 'gcp_list.txt'], ['#export-check', 'check_list.txt']]) {
    await page.click(button);
    const target = path.join(exportDir, file);
    for (let t = 0; t < 100 && !fs.existsSync(target); ++t) await new Promise(r => setTimeout(r, 100));
    if (!fs.existsSync(target)) { fail('no download of ' + file); continue; }
    const text = fs.readFileSync(target, 'utf8');
    console.log(`${file}:\n${text}`);
  }
  if (errors.length) fail('errors in the page: ' + errors.join('; '));
  if (requests.length) fail('the page asked the network for: ' + requests.join(', '));
} finally {
  await browser.close();
  fs.rmSync(profile, { recursive: true, force: true });
}
if (failures) process.exit(1);
console.log('ok: the page loaded offline, showed the w-test rejection, took a drag, a rejection, a placement and ' +
            'a nudge, and exported both lists');
