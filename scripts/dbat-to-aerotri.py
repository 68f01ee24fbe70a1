#!/usr/bin/env python3
"""States a DBAT project (DBAT's script XML) in aerotri's own files.

Usage: scripts/dbat-to-aerotri.py PROJECT.xml OUTDIR

Writes into OUTDIR:
  control.txt   LOCAL control marks, sigma_x/y/z per point, sigma_px per mark
  checks.txt    the check points' marks (DBAT's <check_pts>), same form
  ties.txt      tie-point marks: image point im_x im_y sigma_px=S
  camera.txt    the certificate: every parameter 'fixed' when DBAT does not
                estimate the interior orientation
and prints the aerotri command that adjusts it (pixels from the image's outer
corner: --gcp-pixel-origin corner).

What DBAT's files mean (DBAT's own documentation and sxb example):
  - image points 'id,im,x,y' in pixels, the top-left pixel's centre at
    (0.5, 0.5), y down; the sigma is the file's sxy attribute;
  - control 'id,label,x,y,z,sx,sy,sz' in one Cartesian frame (metres);
  - camera <cc> camera constant and <pp> principal point in the camera unit
    (mm), from the sensor's top-left corner with y down (PhotoModeler's
    convention); <sensor> is the format in mm and <image> in pixels.
Only what aerotri models is converted: a project that estimates the interior
orientation or uses distortion is refused with the reason.
"""
import os
import sys
import xml.etree.ElementTree as ET


def fail(message):
    sys.stderr.write("dbat-to-aerotri: " + message + "\n")
    sys.exit(1)


def numbers(text, count, where):
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != count:
        fail(f"{where}: '{text}': expected {count} comma-separated numbers")
    try:
        return [float(p) for p in parts]
    except ValueError:
        fail(f"{where}: '{text}': expected numbers")


def read_rows(path, min_fields):
    rows = []
    if not os.path.isfile(path):
        fail(f"{path}: no such file (named in the project XML)")
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, 1):
            line = line.strip()
            if not line or line.startswith("#") or line.startswith("%"):
                continue
            fields = [x.strip() for x in line.split(",")]
            if len(fields) < min_fields:
                fail(f"{path}:{number}: '{line}': expected at least {min_fields} fields")
            rows.append((number, fields))
    return rows


def id_filter(element):
    """(ids, keep) of a <filter id="a,b">keep|remove</filter>, or None."""
    filt = element.find("filter")
    if filt is None:
        return None
    ids = {x.strip() for x in filt.get("id", "").split(",") if x.strip()}
    mode = (filt.text or "").strip()
    if mode not in ("keep", "remove"):
        fail(f"filter '{mode}': expected keep or remove")
    return ids, mode == "keep"


def read_points(element, base):
    """{id: (label, x, y, z, sx, sy, sz)} of a <ctrl_pts> or <check_pts>."""
    if element is None:
        return {}
    file_el = element.find("file")
    fmt = file_el.get("format", "")
    if fmt != "id,label,x,y,z,sx,sy,sz":
        fail(f"{file_el.text}: format '{fmt}': expected id,label,x,y,z,sx,sy,sz")
    path = os.path.join(base, file_el.text.strip())
    chosen = id_filter(element)
    points = {}
    for number, f in read_rows(path, 8):
        if chosen is not None and ((f[0] in chosen[0]) != chosen[1]):
            continue
        try:
            points[f[0]] = (f[1],) + tuple(float(v) for v in f[2:8])
        except ValueError:
            fail(f"{path}:{number}: expected numbers for x, y, z, sx, sy, sz")
    return points


def main():
    if len(sys.argv) != 3:
        sys.stderr.write(__doc__)
        sys.exit(2)
    project, out = sys.argv[1], sys.argv[2]
    base = os.path.dirname(os.path.abspath(project))
    try:
        root = ET.parse(project).getroot()
    except (OSError, ET.ParseError) as e:
        fail(f"{project}: {e}: expected DBAT's project XML")
    inp = root.find("input")
    for need in ("input", "input/images/file", "input/cameras/camera", "input/image_pts/file"):
        if root.find(need) is None:
            fail(f"{project}: no <{need}> element: expected DBAT's project XML (<document><input>...)")
    if inp.get("base_dir", "$HERE") != "$HERE":
        fail(f"{project}: input base_dir '{inp.get('base_dir')}': only $HERE is supported")

    images = {}
    images_el = inp.find("images/file")
    for _, f in read_rows(os.path.join(base, images_el.text.strip()), 2):
        images[f[0]] = os.path.basename(f[1])

    cam = inp.find("cameras/camera")
    unit = cam.findtext("unit", "mm").strip()
    sensor_w, sensor_h = numbers(cam.findtext("sensor"), 2, "sensor")
    width, height = (int(v) for v in numbers(cam.findtext("image"), 2, "image"))
    cc = float(cam.findtext("cc"))
    ppx, ppy = numbers(cam.findtext("pp"), 2, "pp")
    distortion = numbers(cam.findtext("K", "0,0,0"), 3, "K") + numbers(cam.findtext("P", "0,0"), 2, "P")
    if any(d != 0 for d in distortion):
        fail("lens distortion in DBAT's backward model is not converted (aerotri's is forward, Brown)")
    estimate_io = (root.findtext("operations/operation/set_bundle_estimate_params/io") or "false").strip()
    if estimate_io != "false":
        fail(f"<io>{estimate_io}</io>: only a fixed interior orientation is converted")
    pixel_w, pixel_h = sensor_w / width, sensor_h / height
    if abs(pixel_w - pixel_h) > 1e-9 * pixel_w:
        fail(f"pixels {pixel_w} x {pixel_h} {unit}: only square pixels are converted")
    # aerotri's pixel convention: the top-left pixel's centre at (0, 0).
    cx = ppx / pixel_w - 0.5
    cy = ppy / pixel_h - 0.5

    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, "camera.txt"), "w") as f:
        f.write(f"# {os.path.basename(project)}: {cam.findtext('name', '').strip()}, "
                f"camera constant {cc} {unit}, principal point ({ppx}, {ppy}) {unit} from the "
                f"top-left corner, {pixel_w} {unit} pixels\n")
        f.write(f"width {width}\nheight {height}\n")
        f.write(f"f {cc / pixel_w:.6f} fixed\ncx {cx:.6f} fixed\ncy {cy:.6f} fixed\n")
        for name in ("k1", "k2", "k3", "p1", "p2"):
            f.write(f"{name} 0 fixed\n")

    control = read_points(inp.find("ctrl_pts"), base)
    checks = read_points(inp.find("check_pts"), base)
    marks = {}   # point id -> [(image name, x, y, sigma)]
    ties = []
    for file_el in inp.findall("image_pts/file"):
        if file_el.get("format", "") != "id,im,x,y":
            fail(f"{file_el.text}: format '{file_el.get('format')}': expected id,im,x,y")
        sigma = float(file_el.get("sxy", "1"))
        path = os.path.join(base, file_el.text.strip())
        for number, f in read_rows(path, 4):
            if f[1] not in images:
                fail(f"{path}:{number}: image '{f[1]}': not in the project's image list")
            try:
                mark = (images[f[1]], float(f[2]), float(f[3]), sigma)
            except ValueError:
                fail(f"{path}:{number}: '{f[2]}, {f[3]}': expected pixel coordinates x, y")
            if f[0] in control or f[0] in checks:
                marks.setdefault(f[0], []).append(mark)
            else:
                ties.append((f[0],) + mark)

    def write_points(name, points):
        with open(os.path.join(out, name), "w") as f:
            f.write("LOCAL\n")
            for pid, (label, x, y, z, sx, sy, sz) in sorted(points.items()):
                for image, u, v, s in marks.get(pid, []):
                    f.write(f"{x} {y} {z} {u} {v} {image} {pid} sigma_x={sx} sigma_y={sy} "
                            f"sigma_z={sz} sigma_px={s}\n")

    write_points("control.txt", control)
    write_points("checks.txt", checks)
    with open(os.path.join(out, "ties.txt"), "w") as f:
        for pid, image, u, v, s in ties:
            f.write(f"{image} {pid} {u} {v} sigma_px={s}\n")
    print(f"aerotri adjust --measurements {out}/ties.txt --camera-file {out}/camera.txt "
          f"--gcp {out}/control.txt --checkpoints {out}/checks.txt --gcp-pixel-origin corner "
          f"--checkpoints-in-bundle")


if __name__ == "__main__":
    main()
