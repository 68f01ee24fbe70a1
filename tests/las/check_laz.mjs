// Independent check of aerotri's LAZ: laz-perf (npm, Hobu's LASzip-compatible
// decoder, compiled to WebAssembly; not aerotri code) decodes FILE.laz, and
// every byte of every point record must equal FILE.las's; the headers agree
// (version, format, count, scales, offsets, bounds) and the CRS VLR is kept.
// Usage: node check_laz.mjs FILE.las FILE.laz   (exit 77 = skipped)
import fs from 'node:fs';
import { createRequire } from 'node:module';

let Las, createLazPerf;
try {
  const require = createRequire((process.env.AEROTRI_NODE_MODULES || '.') + '/');
  ({ Las } = require('copc'));
  ({ createLazPerf } = require('laz-perf'));
} catch (e) {
  console.log('copc.js / laz-perf not installed (scripts/install-test-tools.sh): skipped');
  process.exit(77);
}
const [lasFile, lazFile] = process.argv.slice(2);
const fail = (msg) => { console.error('FAIL: ' + msg); process.exit(1); };
const las = new Uint8Array(fs.readFileSync(lasFile));
const laz = new Uint8Array(fs.readFileSync(lazFile));
const h1 = Las.Header.parse(las.subarray(0, 375));
const h2 = Las.Header.parse(laz.subarray(0, 375));
if (laz[104] !== (0x80 | h1.pointDataRecordFormat)) fail(`LAZ format byte ${laz[104]}`);
for (const key of ['majorVersion', 'minorVersion', 'pointDataRecordFormat', 'pointDataRecordLength', 'pointCount']) {
  if (h1[key] !== h2[key]) fail(`${key}: LAS ${h1[key]}, LAZ ${h2[key]}`);
}
for (const key of ['scale', 'offset', 'min', 'max']) {
  for (let k = 0; k < 3; ++k) if (h1[key][k] !== h2[key][k]) fail(`${key}[${k}]: LAS ${h1[key][k]}, LAZ ${h2[key][k]}`);
}
const vlrs = await Las.Vlr.walk(async (b, e) => laz.subarray(b, e), h2);
if (!vlrs.find((v) => v.userId === 'laszip encoded' && v.recordId === 22204)) fail('no LASzip VLR');
if (!vlrs.find((v) => v.userId === 'LASF_Projection' && v.recordId === 2112)) fail('no CRS VLR');
const LazPerf = await createLazPerf();
const decoded = await Las.PointData.decompressFile(laz, LazPerf);
const raw = las.subarray(h1.pointDataOffset, h1.pointDataOffset + h1.pointCount * h1.pointDataRecordLength);
if (decoded.length !== raw.length) fail(`decoded ${decoded.length} bytes, LAS has ${raw.length}`);
const n = h1.pointDataRecordLength;
for (let i = 0; i < raw.length; ++i) {
  if (raw[i] !== decoded[i]) fail(`point ${Math.floor(i / n)} byte ${i % n}: LAS ${raw[i]}, LAZ ${decoded[i]}`);
}
console.log(`ok: ${h1.pointCount} points, every byte of every record equal; ` +
            `LAZ ${(laz.length / 1e6).toFixed(2)} MB = ${(laz.length / las.length).toFixed(3)} x LAS ${(las.length / 1e6).toFixed(2)} MB`);
