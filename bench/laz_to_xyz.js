// Decompresses a LAS/LAZ file with copc.js + laz-perf (npm, installed by
// scripts/install-test-tools.sh into build/node_modules) and writes every
// n-th point as 'x y z' text, for bench/dsm_vs_points. Benchmark helper.
//   AEROTRI_NODE_MODULES=build/node_modules node bench/laz_to_xyz.js IN.laz OUT.xyz
const {createRequire}=require('module'); const r=createRequire(process.env.AEROTRI_NODE_MODULES+'/');
const {Las}=r('copc'); const fs=require('fs');
(async () => {
  const {createLazPerf} = r('laz-perf');
  const LazPerf = await createLazPerf();
  const file = new Uint8Array(fs.readFileSync(process.argv[2]));
  const header = Las.Header.parse(file.subarray(0, 375));
  console.error('LAS', header.majorVersion + '.' + header.minorVersion, 'format', header.pointDataRecordFormat, 'points', header.pointCount);
  const data = await Las.PointData.decompressFile(file, LazPerf);
  const view = Las.View.create(data, header);
  const gx = view.getter('X'), gy = view.getter('Y'), gz = view.getter('Z');
  const step = Math.max(1, Math.floor(header.pointCount / 200000));
  let out = [];
  for (let i = 0; i < header.pointCount; i += step) out.push(gx(i).toFixed(3) + ' ' + gy(i).toFixed(3) + ' ' + gz(i).toFixed(3));
  fs.writeFileSync(process.argv[3], out.join('\n') + '\n');
  console.error('wrote', out.length);
})().catch(e => { console.error(e); process.exit(1); });
