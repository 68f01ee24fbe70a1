// Independent check of aerotri's LAS 1.4 output with copc.js (npm "copc",
// Connor Manning's LAS 1.4 / COPC reader; not aerotri code): version, point
// format, count, bounds, coordinates to the millimetre, 16-bit colours,
// ASPRS classes, and the OGC WKT CRS record.
// Usage: node check_las.mjs FILE.las EXPECTED.json   (exit 77 = skipped)
// The package lives in build/node_modules (scripts/install-test-tools.sh),
// named by AEROTRI_NODE_MODULES.
import fs from 'node:fs';
import { createRequire } from 'node:module';

let Las;
try {
  const require = createRequire((process.env.AEROTRI_NODE_MODULES || '.') + '/');
  ({ Las } = require('copc'));
} catch (e) {
  console.log('copc.js not installed (scripts/install-test-tools.sh): skipped');
  process.exit(77);
}
const [file, expectedFile] = process.argv.slice(2);
const expected = JSON.parse(fs.readFileSync(expectedFile, 'utf8'));
const bytes = new Uint8Array(fs.readFileSync(file));
const fail = (msg) => { console.error('FAIL: ' + msg); process.exit(1); };

const header = Las.Header.parse(bytes.subarray(0, 375));
if (header.majorVersion !== 1 || header.minorVersion !== 4) fail(`version ${header.majorVersion}.${header.minorVersion}`);
if (header.pointDataRecordFormat !== 7) fail(`point format ${header.pointDataRecordFormat}`);
if (header.pointCount !== expected.count) fail(`count ${header.pointCount} != ${expected.count}`);
for (let k = 0; k < 3; ++k) {
  if (header.scale[k] !== 0.001) fail(`scale[${k}] ${header.scale[k]}`);
  if (Math.abs(header.min[k] - expected.min[k]) > 0.0015) fail(`min[${k}] ${header.min[k]} != ${expected.min[k]}`);
  if (Math.abs(header.max[k] - expected.max[k]) > 0.0015) fail(`max[${k}] ${header.max[k]} != ${expected.max[k]}`);
}
const view = Las.View.create(bytes.subarray(header.pointDataOffset), header);
const get = Object.fromEntries(['X', 'Y', 'Z', 'Red', 'Green', 'Blue', 'Classification'].map((d) => [d, view.getter(d)]));
for (const p of expected.points) {
  for (const [dim, axis] of [['X', 'x'], ['Y', 'y'], ['Z', 'z']]) {
    const got = get[dim](p.index);
    if (Math.abs(got - p[axis]) > 0.0006) fail(`point ${p.index} ${axis}: ${got} != ${p[axis]}`);
  }
  for (const [dim, c] of [['Red', 'r'], ['Green', 'g'], ['Blue', 'b']]) {
    if (get[dim](p.index) !== p[c] * 257) fail(`point ${p.index} ${dim} ${get[dim](p.index)} != ${p[c] * 257}`);
  }
  if (get.Classification(p.index) !== p.class) fail(`point ${p.index} class ${get.Classification(p.index)} != ${p.class}`);
}
const vlrs = await Las.Vlr.walk(async (b, e) => bytes.subarray(b, e), header);
const wkt = vlrs.find((v) => v.userId === 'LASF_Projection' && v.recordId === 2112);
if (!wkt) fail('no OGC WKT VLR (LASF_Projection 2112)');
const text = new TextDecoder().decode(bytes.subarray(wkt.contentOffset, wkt.contentOffset + wkt.contentLength));
if (!text.includes('UTM zone 32N')) fail('WKT does not name UTM zone 32N: ' + text.slice(0, 80));
console.log(`ok: LAS ${header.majorVersion}.${header.minorVersion} format ${header.pointDataRecordFormat}, ` +
            `${header.pointCount} points, CRS WKT present`);
