// Independent check of aerotri's COPC with copc.js and laz-perf (npm; not
// aerotri code): the COPC info and hierarchy are read as a viewer reads them,
// the hierarchy walked from the root, every node's chunk decoded in place; each
// point lies in its node's cube, every point of the LAS is reached exactly
// once (the multisets of whole records are equal), and the file also decodes
// front to back as plain LAZ through its chunk table.
// Usage: node check_copc.mjs FILE.las FILE.copc.laz   (exit 77 = skipped)
import fs from 'node:fs';
import { createRequire } from 'node:module';

let Las, Copc, createLazPerf;
try {
  const require = createRequire((process.env.AEROTRI_NODE_MODULES || '.') + '/');
  ({ Las, Copc } = require('copc'));
  ({ createLazPerf } = require('laz-perf'));
} catch (e) {
  console.log('copc.js / laz-perf not installed (scripts/install-test-tools.sh): skipped');
  process.exit(77);
}
const [lasFile, copcFile] = process.argv.slice(2);
const fail = (msg) => { console.error('FAIL: ' + msg); process.exit(1); };
const las = new Uint8Array(fs.readFileSync(lasFile));
const file = new Uint8Array(fs.readFileSync(copcFile));
const get = async (b, e) => file.subarray(b, e);
const lazPerf = await createLazPerf();

// A 53-bit hash of each 36-byte record, sorted: equal arrays, equal multisets.
function hashes(bytes, count, length) {
  const out = new Float64Array(count);
  for (let i = 0; i < count; ++i) {
    let a = 0x811c9dc5, b = 0x01000193;
    for (let j = 0; j < length; ++j) {
      const v = bytes[i * length + j];
      a = Math.imul(a ^ v, 0x01000193) >>> 0;
      b = Math.imul(b ^ (v + j), 0x5bd1e995) >>> 0;
    }
    out[i] = a * 2097152 + (b >>> 11);
  }
  return out.sort();
}
const same = (x, y) => x.length === y.length && x.every((v, i) => v === y[i]);

const h = Las.Header.parse(las.subarray(0, 375));
const n = h.pointDataRecordLength;
const want = hashes(las.subarray(h.pointDataOffset), h.pointCount, n);

const copc = await Copc.create(get);
if (copc.vlrs[0].userId !== 'copc' || copc.vlrs[0].recordId !== 1) fail('the COPC info VLR is not the first VLR');
if (copc.header.pointCount !== h.pointCount) fail(`COPC count ${copc.header.pointCount} != LAS ${h.pointCount}`);
if (!copc.wkt) fail('no CRS WKT');
const [x0, y0, z0, x1, y1, z1] = copc.info.cube;
const { nodes, pages } = await Copc.loadHierarchyPage(get, copc.info.rootHierarchyPage);
if (Object.keys(pages).length) fail('unexpected child hierarchy pages');
if (!nodes['0-0-0-0']) fail('no root node');
// Every node but the root has its parent in the hierarchy.
for (const key of Object.keys(nodes)) {
  const [d, x, y, z] = key.split('-').map(Number);
  if (d > 0 && !nodes[`${d - 1}-${x >> 1}-${y >> 1}-${z >> 1}`]) fail(`node ${key} without its parent`);
}
const all = new Uint8Array(h.pointCount * n);
let reached = 0, levels = 0;
for (const [key, node] of Object.entries(nodes)) {
  if (node.pointCount === 0) continue;
  const [d, x, y, z] = key.split('-').map(Number);
  levels = Math.max(levels, d);
  const size = (x1 - x0) / 2 ** d;
  const lo = [x0 + x * size, y0 + y * size, z0 + z * size];
  const buffer = await Copc.loadPointDataBuffer(get, copc.header, node, lazPerf);
  const view = Las.View.create(buffer, copc.header);
  const g = ['X', 'Y', 'Z'].map((dim) => view.getter(dim));
  for (let i = 0; i < node.pointCount; ++i) {
    for (let k = 0; k < 3; ++k) {
      const v = g[k](i);
      if (v < lo[k] - 5e-4 || v > lo[k] + size + 5e-4) fail(`node ${key} point ${i}: ${'XYZ'[k]} ${v} outside [${lo[k]}, ${lo[k] + size}]`);
    }
  }
  if (reached + node.pointCount > h.pointCount) fail('more points in the nodes than in the header');
  all.set(buffer, reached * n);
  reached += node.pointCount;
}
if (reached !== h.pointCount) fail(`nodes hold ${reached} points, the header ${h.pointCount}`);
if (!same(hashes(all, reached, n), want)) fail('the nodes\' points are not the LAS\'s points, each once');
// The same file as plain LAZ, through the chunk table.
const whole = await Las.PointData.decompressFile(file, lazPerf);
if (!same(hashes(whole, h.pointCount, n), want)) fail('read as plain LAZ, the points are not the LAS\'s');
console.log(`ok: ${reached} points in ${Object.values(nodes).filter((v) => v.pointCount > 0).length} nodes ` +
            `(levels 0-${levels}), each once and inside its node; COPC ${(file.length / 1e6).toFixed(2)} MB = ` +
            `${(file.length / las.length).toFixed(3)} x LAS`);
