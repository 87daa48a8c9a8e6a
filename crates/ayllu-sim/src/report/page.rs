//! `index.html`: the report as one self-contained page.
//!
//! Promises: no external resource of any kind (styles and scripts inline, plots as inline SVG
//! markup, data as inline JSON), so the folder can be mailed or opened offline; every string
//! from the report reaches the page escaped (HTML text escaped; the JSON data block cannot end
//! its `<script>` early); script errors are counted on `<body data-errors>` and shown in a red
//! box, so a broken page is visibly broken, to people and to tests.

use std::fmt::Write as _;

use serde_json::json;

use super::plots::{self, Plot};
use super::tables;
use super::Report;

const CSS: &str = include_str!("../../assets/report.css");
const REPLAY_JS: &str = include_str!("../../assets/replay.js");

/// Runs before any other script so that errors in them are caught. It can only count errors
/// from scripts that come after it, hence its place at the top of `<body>`.
const ERROR_TRAP: &str = r#"(function () {
  var count = 0;
  function record(message) {
    count += 1;
    document.body.dataset.errors = String(count);
    var box = document.getElementById('errors');
    box.hidden = false;
    var li = document.createElement('li');
    li.textContent = message;
    box.querySelector('ul').appendChild(li);
  }
  window.onerror = function (message, source, line, column) {
    record(String(message) + ' (line ' + line + ':' + column + ')');
  };
  window.addEventListener('unhandledrejection', function (event) {
    record('unhandled promise rejection: ' + String(event.reason));
  });
})();"#;

pub(super) fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// JSON safe to put between `<script type="application/json">` and `</script>`. A `<` can only
/// occur inside JSON strings, where `\u003c` means the same; writing every `<` that way rules
/// out both `</script>` and the `<!--` that sends the HTML parser into its escaped-script
/// states, which replacing only `</` would not. `>` and `&` go the same way for symmetry.
pub(super) fn script_json(value: &serde_json::Value) -> String {
    let text = value.to_string();
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '<' => out.push_str("\\u003c"),
            '>' => out.push_str("\\u003e"),
            '&' => out.push_str("\\u0026"),
            _ => out.push(c),
        }
    }
    out
}

/// What the replay script reads: the recording, the coverage series with the controllers'
/// colours (the timeline draws the replayed controller's coverage in its plot colour). Numbers
/// are rounded (see [`round_floats`]); `results.json` keeps them exact.
fn data(report: &Report) -> serde_json::Value {
    let colours = plots::controllers(report);
    let colour_of = |name: &str| colours.iter().find(|(n, _)| n == name).map(|(_, c)| plots::hex(*c));
    let coverage: Vec<serde_json::Value> = report
        .coverage
        .iter()
        .map(|(name, s)| {
            json!({"name": name, "colour": colour_of(name), "t": s.t, "observed": s.observed, "weighted": s.weighted})
        })
        .collect();
    let mut value = json!({"recording": report.recording, "coverage": coverage});
    round_floats(&mut value);
    value
}

/// Rounds every non-integer number to 4 decimals (0.1 mm, 0.1 mrad): far below what a canvas
/// shows, and it halves the page of a long run, whose frames are most of its bytes.
fn round_floats(value: &mut serde_json::Value) {
    use serde_json::Value;
    match value {
        Value::Number(n) if n.is_f64() => {
            let x = n.as_f64().unwrap_or(0.0);
            if let Some(r) = serde_json::Number::from_f64((x * 1e4).round() / 1e4) {
                *n = r;
            }
        }
        Value::Array(items) => items.iter_mut().for_each(round_floats),
        Value::Object(map) => map.values_mut().for_each(round_floats),
        _ => {}
    }
}

fn run_facts(report: &Report) -> String {
    let m = &report.recording.meta;
    let facts: [(&str, String); 9] = [
        ("controller", m.controller.clone()),
        ("seed", m.seed.to_string()),
        ("radio loss", format!("{} %", tables::percent(m.loss))),
        ("arena", format!("{} × {} m", m.arena[0], m.arena[1])),
        ("robots / targets", format!("{} / {}", report.recording.robots.len(), report.recording.targets.len())),
        ("camera", format!("{:.0}° field of view, {} m range", m.camera_fov.to_degrees(), m.camera_range)),
        ("observe range", format!("{} m", m.observe_range)),
        ("run length", format!("{} s, a frame every {} s", m.duration, m.frame_dt)),
        (
            "events",
            if report.recording.events.is_empty() {
                "none".to_string()
            } else {
                report
                    .recording
                    .events
                    .iter()
                    .map(|e| format!("R{} {} at {:.1} s", e.robot, e.kind, e.t))
                    .collect::<Vec<_>>()
                    .join("; ")
            },
        ),
    ];
    let mut out = String::from("<dl class=\"run\">");
    for (k, v) in facts {
        let _ = write!(out, "<dt>{}</dt><dd>{}</dd>", escape(k), escape(&v));
    }
    out.push_str("</dl>");
    out
}

/// Small inline pictures for the legend, drawn like the canvas draws them.
const LEGEND: &str = r##"<ul class="legend">
<li><svg width="34" height="14"><line x1="2" y1="7" x2="32" y2="7" stroke="#1f77b4" stroke-width="2.5"/></svg>robot drives to the target and claims it (BLE)</li>
<li><svg width="34" height="14"><line x1="2" y1="7" x2="32" y2="7" stroke="#1f77b4" stroke-width="1.8" stroke-dasharray="6 5"/></svg>drives to the target without a claim</li>
<li><svg width="34" height="14"><path d="M4 7 L30 1 A26 26 0 0 1 30 13 Z" fill="#1f77b4" fill-opacity="0.12" stroke="#1f77b4" stroke-opacity="0.3"/></svg>camera field of view; darker part: within observe range</li>
<li><svg width="34" height="14"><circle cx="17" cy="7" r="5" fill="#c0281e" stroke="#6b1d12"/><circle cx="17" cy="7" r="6.5" fill="none" stroke="#1a9850" stroke-width="2"/></svg>target (redder and larger: higher priority w); green ring: observed</li>
<li><svg width="34" height="14"><circle cx="17" cy="7" r="6" fill="#a9a9a9"/><path d="M12 2 L22 12 M22 2 L12 12" stroke="#c81e1e" stroke-width="2"/></svg>robot killed; red marks on the timeline</li>
<li>“claims T2”: this robot's BLE claim; “inhib T1”: its T1 observer layer is write-inhibited by a peer</li>
</ul>"##;

const DEFINITIONS: &str = r#"<dl class="defs">
<dt>A</dt><dd>average number of targets observed over the run (Parker's A); A/m divides by the number of targets m.</dd>
<dt>A_w</dt><dd>priority-weighted fraction of targets observed, 0..1: Σ w_j o_j(t) / Σ w_j averaged over time; ± one standard deviation over seeds.</dd>
<dt>top-k</dt><dd>mean fraction observed of the k = min(robots, m) highest-priority targets, the ones a perfect team could always cover.</dd>
<dt>redundant</dt><dd>mean number of robot-observations beyond the first per target (robots watching an already watched target).</dd>
<dt>switches/min</dt><dd>changes of the target driving a robot (including to and from none), per live robot per minute.</dd>
<dt>recover s</dt><dd>after a kill, mean time until the targets the dead robot observed are observed again ("-": no kill, or nothing to re-cover).</dd>
<dt>msgs/robot/s</dt><dd>radio messages sent per robot per second (a broadcast counts once per sender).</dd>
</dl>"#;

pub(super) fn render(report: &Report, plots: &[Plot]) -> String {
    let title = escape(&report.title);
    let mut out = String::with_capacity(64 * 1024);
    let _ = write!(
        out,
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
{CSS}</style>
</head>
<body data-status="loading" data-errors="0">
<div id="errors" class="errors" hidden>Script errors on this page; the replay may be wrong or missing.<ul></ul></div>
<script>
{ERROR_TRAP}
</script>
<h1>{title}</h1>
<pre class="command">$ {command}</pre>
<section class="replay">
<div class="stage">
<canvas id="arena" width="780" height="560" aria-label="replay of the recorded run"></canvas>
<div class="controls">
<button id="play" type="button">▶ Play</button>
<button id="back" class="step" type="button" title="previous frame (←)">◀</button>
<button id="fwd" class="step" type="button" title="next frame (→)">▶</button>
<label>speed <select id="speed">
<option value="0.5">0.5×</option><option value="1">1×</option><option value="2">2×</option>
<option value="5" selected>5×</option><option value="10">10×</option><option value="20">20×</option>
<option value="50">50×</option></select></label>
<input id="slider" type="range" min="0" max="1" step="0.1" value="0" aria-label="time">
<span id="clock" class="mono"></span>
</div>
<canvas id="timeline" width="780" height="58" aria-label="timeline: coverage and events; click to seek"></canvas>
</div>
<aside class="panel">
<h3>Robots now</h3>
<table class="state"><thead><tr><th>robot</th><th>drive</th><th>claims</th><th>inhibited</th><th>observing</th></tr></thead>
<tbody id="robots-state"></tbody></table>
<h3>Targets now</h3>
<table class="state"><thead><tr><th>target</th><th>priority</th><th>observed by</th><th>claimed by</th></tr></thead>
<tbody id="targets-state"></tbody></table>
<h3>Run</h3>
{facts}
<h3>Legend</h3>
{LEGEND}
</aside>
</section>
"#,
        command = escape(&report.command),
        facts = run_facts(report),
    );

    out.push_str("<section class=\"tables\">\n");
    for (i, (name, rows)) in tables::sections(report).into_iter().enumerate() {
        let _ = writeln!(out, "<h2>{}</h2>", escape(name));
        let table = tables::html(rows, escape);
        // The sweep is long; the plots summarise it, the table is there to look a number up.
        if i == 2 && rows.len() > 12 {
            let _ = write!(out, "<details><summary>show all {} rows</summary>\n{table}</details>\n", rows.len());
        } else {
            out.push_str(&table);
        }
    }
    let _ = write!(out, "<h3>Columns</h3>\n{DEFINITIONS}\n</section>\n");

    out.push_str("<section class=\"plots\">\n<h2>Plots</h2>\n");
    for plot in plots {
        let _ = write!(
            out,
            "<figure id=\"{id}\">\n{svg}\n<figcaption>{caption} <span class=\"mono\">({file})</span></figcaption>\n</figure>\n",
            id = plot.file.trim_end_matches(".svg"),
            svg = plot.svg,
            caption = escape(&plot.caption),
            file = plot.file,
        );
    }
    out.push_str("</section>\n");

    let _ = write!(
        out,
        "<script type=\"application/json\" id=\"data\">{}</script>\n<script>\n{REPLAY_JS}</script>\n</body>\n</html>\n",
        script_json(&data(report)),
    );
    out
}
