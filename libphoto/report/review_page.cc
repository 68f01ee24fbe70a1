// SPDX-License-Identifier: BSD-3-Clause
#include "libphoto/report/review_page.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "libphoto/report/html_report.h"

namespace aerotri {
namespace {

using json = nlohmann::json;

// The page's script and styles; the data go in a <script type="application/json">.
extern const char* const kReviewStyle;
extern const char* const kReviewScript;

// JSON inside <script>: "</" would end the element.
std::string ScriptSafe(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (size_t i = 0; i < s.size(); ++i) {
    out += s[i];
    if (s[i] == '<' && i + 1 < s.size() && s[i + 1] == '/') out += "\\";
  }
  return out;
}

// chip_size x chip_size photo pixels from (ox, oy), grey outside the photo,
// as an inline JPEG.
std::string ChipDataUrl(const cv::Mat& photo, int ox, int oy, const ReviewPageOptions& options) {
  cv::Mat chip(options.chip_size, options.chip_size, CV_8UC3, cv::Scalar(128, 128, 128));
  if (!photo.empty()) {
    cv::Mat colour = photo;
    if (photo.channels() == 1) cv::cvtColor(photo, colour, cv::COLOR_GRAY2BGR);
    const cv::Rect want(ox, oy, options.chip_size, options.chip_size);
    const cv::Rect have = want & cv::Rect(0, 0, colour.cols, colour.rows);
    if (have.area() > 0) colour(have).copyTo(chip(cv::Rect(have.x - ox, have.y - oy, have.width, have.height)));
  }
  std::vector<uchar> jpeg;
  cv::imencode(".jpg", chip, jpeg, {cv::IMWRITE_JPEG_QUALITY, options.jpeg_quality});
  return "data:image/jpeg;base64," + Base64(std::string(jpeg.begin(), jpeg.end()));
}

// The page's data: per point its coordinates line fields and per photo the
// chip, the prediction, the mark and the adjustment's verdict on it.
json PageData(const ReviewPageInput& in, const std::function<cv::Mat(const std::string&)>& load_image,
              const ReviewPageOptions& options) {
  std::map<std::pair<std::string, std::string>, json> adjusted;
  if (in.adjustment_marks.is_array()) {
    for (const json& m : in.adjustment_marks) adjusted[{m.value("point", ""), m.value("image", "")}] = m;
  }
  json points = json::array();
  // Chips are cut photo by photo, each photo read once.
  std::map<std::string, std::vector<std::pair<size_t, size_t>>> by_image;
  for (const json& p : in.marking.value("points", json::array())) {
    const bool check = p.value("role", "control") == "check";
    json point = {{"name", p.value("name", "")},
                  {"role", check ? "check" : "control"},
                  {"status", p.value("status", "")},
                  {"reason", p.value("reason", "")},
                  {"coordinates", p.value("coordinates", "")},
                  {"sigmas", p.value("sigmas", "")},
                  {"photos", json::array()}};
    for (const json& m : p.value("photos", json::array())) {
      const bool marked = m.value("marked", false);
      const json& at = marked ? m["xy_px"] : m["predicted_px"];
      const int half = options.chip_size / 2;
      json photo = {{"image", m.value("image", "")},
                    {"ox", static_cast<int>(std::lround(at[0].get<double>())) - half},
                    {"oy", static_cast<int>(std::lround(at[1].get<double>())) - half},
                    {"predicted", m["predicted_px"]},
                    {"mark", marked ? m["xy_px"] : json()}};
      if (marked) {
        photo["confidence"] = m.value("confidence", 0.0);
        photo["kind"] = m.value("kind", "");
        photo["reprojection_px"] = m.value("reprojection_px", 0.0);
      }
      const auto a = adjusted.find({point["name"].get<std::string>(), photo["image"].get<std::string>()});
      if (a != adjusted.end()) {
        photo["residual_px"] = a->second.value("residual_px", json());
        photo["w"] = a->second.value("w", json());
        photo["rejected_by_adjustment"] = a->second.value("rejected", false);
      }
      by_image[photo["image"].get<std::string>()].push_back({points.size(), point["photos"].size()});
      point["photos"].push_back(photo);
    }
    points.push_back(point);
  }
  for (const auto& [image, chips] : by_image) {
    const cv::Mat photo = load_image(image);
    for (const auto& [i, k] : chips) {
      json& c = points[i]["photos"][k];
      c["chip"] = ChipDataUrl(photo, c["ox"].get<int>(), c["oy"].get<int>(), options);
    }
  }
  const json files = in.marking.value("files", json::object());
  const auto file_of = [&](const char* role, const char* name) -> json {
    if (!files.contains(role)) return nullptr;
    return {{"crs", files[role].value("crs", "")}, {"download", name}, {"source", files[role].value("path", "")}};
  };
  return {{"chip_size", options.chip_size},
          {"scale", options.scale},
          {"adjusted", in.adjustment_marks.is_array()},
          {"search_radius_m", in.marking.value("search_radius_m", 0.0)},
          {"files", {{"control", file_of("control", "gcp_list.txt")}, {"check", file_of("check", "check_list.txt")}}},
          {"points", points}};
}

}  // namespace

std::string RenderReviewPage(const ReviewPageInput& input, const std::function<cv::Mat(const std::string&)>& load_image,
                             const ReviewPageOptions& options) {
  const json data = PageData(input, load_image, options);
  const std::string title = "Ground control marks" + (input.title.empty() ? "" : " — " + input.title);
  std::string html;
  html += "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>\n";
  html += "<meta http-equiv='Content-Security-Policy' content=\"default-src 'none'; img-src data: blob:; "
          "style-src 'unsafe-inline'; script-src 'unsafe-inline'\">\n";
  html += "<title>" + HtmlEscape(title) + "</title>\n<style>" + std::string(kReviewStyle) + "</style></head>\n<body>\n";
  html += "<header><h1>" + HtmlEscape(title) + "</h1>\n";
  html += "<p class='help'>Each chip is a photo where the point was predicted: <span class='pred-key'>+</span> the "
          "point predicted through the georeferenced model (by the photos' GPS, or by the targets found in "
          "them), <span class='mark-key'>&#9675;</span> the mark. Drag a mark "
          "(or click where one is missing) to move it; arrow keys nudge the focused chip's mark by 0.1 px (Shift: "
          "1 px). Accept or reject each mark, or a whole point, then download the corrected files: they are "
          "gcp_list.txt files that <code>aerotri run --gcp</code> and <code>--checkpoints</code> read as they "
          "are.";
  html += data["adjusted"].get<bool>()
              ? " Residuals are the adjustment's (adjusted minus observed); a mark its w-test rejected starts "
                "rejected.</p>\n"
              : " The survey is not adjusted yet: residuals appear once it is (aerotri run, or georeference then "
                "report).</p>\n";
  html += "<div id='summary'></div><div id='exports'></div></header>\n<main id='points'></main>\n";
  html += "<script type='application/json' id='data'>" + ScriptSafe(data.dump()) + "</script>\n";
  html += "<script>" + std::string(kReviewScript) + "</script>\n</body></html>\n";
  return html;
}

namespace {

const char* const kReviewStyle = R"CSS(
body{font-family:system-ui,sans-serif;margin:0;color:#222;background:#fafafa}
header{position:sticky;top:0;background:#fff;border-bottom:1px solid #ccc;padding:8px 16px;z-index:2}
h1{font-size:20px;margin:4px 0}
.help{font-size:13px;max-width:1100px;margin:4px 0}
.pred-key{color:#1565c0;font-weight:bold}.mark-key{color:#d32f2f;font-weight:bold}
#summary{font-size:14px;margin:4px 0}
#exports button{margin-right:8px}
main{padding:8px 16px}
section.point{border:1px solid #ddd;background:#fff;margin:12px 0;padding:8px}
section.point.rejected{opacity:.55}
section.point h2{font-size:16px;margin:2px 0 6px}
.status{font-size:12px;padding:1px 6px;border-radius:3px;margin-left:6px;color:#fff;background:#777}
.status.MARKED{background:#2e7d32}.status.SINGLE_PHOTO{background:#f9a825}
.reason{font-size:13px;color:#8a4b00;margin:2px 0 6px}
.chips{display:flex;flex-wrap:wrap;gap:10px}
figure.chip{margin:0;border:2px solid #ccc;padding:4px;font-size:12px;width:min-content;outline:none}
figure.chip:focus{border-color:#1565c0}
figure.chip.accepted{border-color:#2e7d32}
figure.chip.off .view{filter:grayscale(1) brightness(.8)}
.view{position:relative;cursor:crosshair;touch-action:none}
.view img{display:block;image-rendering:pixelated;user-select:none;-webkit-user-drag:none}
.view svg{position:absolute;left:0;top:0;pointer-events:none}
figcaption{margin-top:4px;line-height:1.35}
.name{font-weight:bold;word-break:break-all}
.verdict{color:#b71c1c}
figcaption button{font-size:12px;margin:2px 4px 0 0}
)CSS";

const char* const kReviewScript = R"JS(
'use strict';
const D = JSON.parse(document.getElementById('data').textContent);
const S = D.scale, N = D.chip_size, V = S * N;
const SVG = 'http://www.w3.org/2000/svg';
const state = D.points.map(p => ({
  rejected: false,
  photos: p.photos.map(c => {
    const s = {xy: c.mark ? c.mark.slice() : null, edited: false};
    s.accepted = !!c.mark && !c.rejected_by_adjustment && (p.status === 'MARKED' || p.status === 'SINGLE_PHOTO');
    return s;
  })
}));
function el(tag, attrs, text) {
  const e = document.createElement(tag);
  for (const k in attrs || {}) e.setAttribute(k, attrs[k]);
  if (text !== undefined) e.textContent = text;
  return e;
}
function svgEl(tag, attrs) {
  const e = document.createElementNS(SVG, tag);
  for (const k in attrs) e.setAttribute(k, attrs[k]);
  return e;
}
const toCss = (c, xy) => [(xy[0] - c.ox + 0.5) * S, (xy[1] - c.oy + 0.5) * S];
const toPx = (c, css) => [c.ox + css[0] / S - 0.5, c.oy + css[1] / S - 0.5];
const f3 = v => v.toFixed(3);
function caption(p, c, s) {
  const parts = [];
  if (c.mark) parts.push('detected (' + c.kind + ', confidence ' + c.confidence.toFixed(2) + ', ray ' + c.reprojection_px.toFixed(2) + ' px)');
  else parts.push('no target detected here');
  if (s.edited && s.xy) {
    parts.push(c.mark ? 'moved ' + Math.hypot(s.xy[0] - c.mark[0], s.xy[1] - c.mark[1]).toFixed(2) + ' px by hand' : 'placed by hand');
  }
  if (s.xy) parts.push('mark (' + s.xy[0].toFixed(2) + ', ' + s.xy[1].toFixed(2) + ')');
  if (c.residual_px) {
    parts.push('residual after adjustment ' + Math.hypot(c.residual_px[0], c.residual_px[1]).toFixed(2) + ' px, w ' +
               Math.max(Math.abs(c.w[0]), Math.abs(c.w[1])).toFixed(1));
  }
  return parts.join('; ');
}
function drawChip(i, k) {
  const p = D.points[i], c = p.photos[k], s = state[i].photos[k], fig = c.fig;
  const on = s.accepted && !state[i].rejected && !!s.xy;
  fig.classList.toggle('accepted', on);
  fig.classList.toggle('off', !on);
  c.mk.style.display = s.xy ? '' : 'none';
  if (s.xy) {
    const [x, y] = toCss(c, s.xy);
    c.mk.setAttribute('transform', 'translate(' + x + ',' + y + ')');
    c.mk.setAttribute('stroke', on ? '#d32f2f' : '#9e9e9e');
  }
  c.text.textContent = caption(p, c, s);
  c.verdict.textContent = c.rejected_by_adjustment
      ? 'rejected by the adjustment\'s w-test' + (s.accepted ? ' (accepted by you)' : ': accept to keep it') : '';
  c.stateText.textContent = on ? 'accepted' : (s.xy ? 'rejected' : 'no mark');
  fig.dataset.state = c.stateText.textContent;
  c.acceptBtn.disabled = !s.xy;
}
function summary() {
  const n = {control: [0, 0], check: [0, 0]};
  D.points.forEach((p, i) => {
    const m = state[i].rejected ? 0 : state[i].photos.filter(s => s.accepted && s.xy).length;
    n[p.role][1] += m;
    if (m > 0) n[p.role][0] += 1;
  });
  const count = (k, one) => k + ' ' + one + (k === 1 ? '' : 's');
  document.getElementById('summary').textContent = 'control: ' + count(n.control[0], 'point') + ', ' +
      count(n.control[1], 'mark') + ' accepted; check points: ' + count(n.check[0], 'point') + ', ' +
      count(n.check[1], 'mark') + ' accepted';
}
function redraw(i) { D.points[i].photos.forEach((c, k) => drawChip(i, k)); D.points[i].section.classList.toggle('rejected', state[i].rejected); summary(); }
function overlay(c) {
  const svg = svgEl('svg', {width: V, height: V, viewBox: '0 0 ' + V + ' ' + V});
  const [px, py] = toCss(c, c.predicted);
  const pred = svgEl('g', {stroke: '#1565c0', 'stroke-width': 2, transform: 'translate(' + px + ',' + py + ')'});
  pred.append(svgEl('line', {x1: -7, y1: 0, x2: 7, y2: 0}), svgEl('line', {x1: 0, y1: -7, x2: 0, y2: 7}));
  const mk = svgEl('g', {fill: 'none', 'stroke-width': 1.5, class: 'mark'});
  mk.append(svgEl('circle', {r: 10}), svgEl('line', {x1: -16, y1: 0, x2: -4, y2: 0}), svgEl('line', {x1: 4, y1: 0, x2: 16, y2: 0}),
            svgEl('line', {x1: 0, y1: -16, x2: 0, y2: -4}), svgEl('line', {x1: 0, y1: 4, x2: 0, y2: 16}));
  svg.append(pred, mk);
  c.mk = mk;
  return svg;
}
function interact(i, k, view) {
  const c = D.points[i].photos[k], s = state[i].photos[k];
  let offset = null;
  const local = e => { const r = view.getBoundingClientRect(); return [e.clientX - r.left, e.clientY - r.top]; };
  view.addEventListener('pointerdown', e => {
    e.preventDefault();
    c.fig.focus();
    view.setPointerCapture(e.pointerId);
    const at = local(e);
    if (s.xy) {
      const m = toCss(c, s.xy);
      offset = Math.hypot(m[0] - at[0], m[1] - at[1]) <= 16 ? [m[0] - at[0], m[1] - at[1]] : [0, 0];
    } else {
      offset = [0, 0];
    }
    if (offset[0] === 0 && offset[1] === 0) { s.xy = toPx(c, at); s.edited = true; s.accepted = true; redraw(i); }
  });
  view.addEventListener('pointermove', e => {
    if (!offset) return;
    const at = local(e);
    s.xy = toPx(c, [at[0] + offset[0], at[1] + offset[1]]);
    s.edited = true;
    s.accepted = true;
    redraw(i);
  });
  const end = () => { offset = null; };
  view.addEventListener('pointerup', end);
  view.addEventListener('pointercancel', end);
  c.fig.addEventListener('keydown', e => {
    const step = e.shiftKey ? 1 : 0.1, d = {ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step]}[e.key];
    if (!d || !s.xy) return;
    e.preventDefault();
    s.xy = [s.xy[0] + d[0], s.xy[1] + d[1]];
    s.edited = true;
    s.accepted = true;
    redraw(i);
  });
}
function chip(i, k) {
  const p = D.points[i], c = p.photos[k], s = state[i].photos[k];
  const fig = el('figure', {class: 'chip', tabindex: 0, 'data-point': p.name, 'data-image': c.image});
  const view = el('div', {class: 'view'});
  view.style.width = view.style.height = V + 'px';
  view.append(el('img', {src: c.chip, width: V, height: V, alt: c.image, draggable: 'false'}), overlay(c));
  const cap = el('figcaption');
  c.fig = fig;
  c.text = el('span', {class: 'detail'});
  c.verdict = el('div', {class: 'verdict'});
  c.stateText = el('b', {class: 'state'});
  c.acceptBtn = el('button', {class: 'accept', type: 'button'}, 'accept');
  const reject = el('button', {class: 'reject', type: 'button'}, 'reject');
  const reset = el('button', {class: 'reset', type: 'button'}, 'reset');
  c.acceptBtn.onclick = () => { s.accepted = true; redraw(i); };
  reject.onclick = () => { s.accepted = false; redraw(i); };
  reset.onclick = () => {
    s.xy = c.mark ? c.mark.slice() : null;
    s.edited = false;
    s.accepted = !!c.mark && !c.rejected_by_adjustment && (p.status === 'MARKED' || p.status === 'SINGLE_PHOTO');
    redraw(i);
  };
  cap.append(el('div', {class: 'name'}, c.image), c.stateText, el('br'), c.text, c.verdict, c.acceptBtn, reject, reset);
  fig.append(view, cap);
  interact(i, k, view);
  return fig;
}
function build() {
  const main = document.getElementById('points');
  D.points.forEach((p, i) => {
    const sec = el('section', {class: 'point', 'data-point': p.name, 'data-role': p.role});
    const h = el('h2', {}, (p.role === 'check' ? 'check point ' : 'control point ') + p.name);
    h.append(el('span', {class: 'status ' + p.status}, p.status));
    const rejectPoint = el('button', {class: 'reject-point', type: 'button'}, 'reject point');
    rejectPoint.onclick = () => {
      state[i].rejected = !state[i].rejected;
      rejectPoint.textContent = state[i].rejected ? 'restore point' : 'reject point';
      redraw(i);
    };
    h.append(' ', rejectPoint);
    sec.append(h);
    if (p.reason) sec.append(el('div', {class: 'reason'}, p.reason));
    if (!p.photos.length) sec.append(el('div', {class: 'reason'}, 'predicted in no photo'));
    const chips = el('div', {class: 'chips'});
    p.photos.forEach((c, k) => chips.append(chip(i, k)));
    sec.append(chips);
    p.section = sec;
    main.append(sec);
    redraw(i);
  });
  summary();
  const exports = document.getElementById('exports');
  for (const role of ['control', 'check']) {
    const f = D.files[role];
    if (!f) continue;
    const b = el('button', {id: 'export-' + role, type: 'button'}, 'download ' + f.download + ' (' + role + ')');
    b.onclick = () => download(f.download, exportText(role));
    exports.append(b);
  }
}
function exportText(role) {
  const lines = [D.files[role].crs];
  D.points.forEach((p, i) => {
    if (p.role !== role || state[i].rejected || !p.coordinates) return;
    p.photos.forEach((c, k) => {
      const s = state[i].photos[k];
      if (s.accepted && s.xy) lines.push(p.coordinates + ' ' + f3(s.xy[0]) + ' ' + f3(s.xy[1]) + ' ' + c.image + ' ' + p.name + p.sigmas);
    });
  });
  return lines.join('\n') + '\n';
}
function download(name, text) {
  const a = el('a', {download: name});
  a.href = URL.createObjectURL(new Blob([text], {type: 'text/plain'}));
  document.body.append(a);
  a.click();
  setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 2000);
}
build();
)JS";

}  // namespace
}  // namespace aerotri
