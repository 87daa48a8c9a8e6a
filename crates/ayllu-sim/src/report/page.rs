//! `index.html`: the report as one self-contained page.
//!
//! Promises: no external resource of any kind (styles and scripts inline, plots as inline SVG
//! markup, data as inline JSON: a menu of the runs and one block per run, parsed only when the
//! run is chosen, so a page of hundreds of runs opens as fast as one of a single run), so the
//! folder can be mailed or opened offline; every string from the report reaches the page
//! escaped (HTML text escaped; no JSON block can end its `<script>` early); script errors are counted on `<body data-errors>` and shown in a red
//! box, so a broken page is visibly broken, to people and to tests.

use std::fmt::Write as _;

use serde_json::json;

use super::plots::{self, Plot};
use super::tables;
use super::{Replay, Report};

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

/// What the replay script reads first: the menu of runs and the controllers' colours (the
/// timeline draws the replayed controller's coverage in its plot colour). Each run's data is a
/// block of its own ([`run_block`]), parsed only when the run is chosen.
fn data(report: &Report) -> serde_json::Value {
    let colours: serde_json::Map<String, serde_json::Value> =
        plots::controllers(report).into_iter().map(|(n, c)| (n, plots::hex(c).into())).collect();
    let runs: Vec<serde_json::Value> = report
        .replays
        .iter()
        .map(|r| json!({"setting": r.setting, "controller": r.meta.controller, "seed": r.meta.seed}))
        .collect();
    json!({"colours": colours, "runs": runs})
}

/// One run's replay as the page embeds it. Numbers are rounded (see [`round_floats`]);
/// `results.json` keeps them exact.
fn run_block(replay: &Replay) -> serde_json::Value {
    let mut value = serde_json::to_value(replay).unwrap_or(serde_json::Value::Null);
    round_floats(&mut value);
    value
}

/// Rounds every non-integer number to 4 decimals (0.1 mm, 0.1 mrad): far below what a canvas
/// shows.
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

/// Seeds as people write them: "seed 1", "seeds 1–10", "seeds 1, 3, 7".
fn seed_list(seeds: &[u64]) -> String {
    let contiguous = seeds.windows(2).all(|w| w[1] == w[0] + 1);
    match seeds {
        [] => "no seed".to_string(),
        [one] => format!("seed {one}"),
        [first, .., last] if contiguous => format!("seeds {first}–{last}"),
        _ => format!("seeds {}", seeds.iter().map(u64::to_string).collect::<Vec<_>>().join(", ")),
    }
}

/// Which runs the menus offer and how they were thinned, said on the page.
fn replay_note(report: &Report) -> String {
    let Some(first) = report.replays.first() else { return "No run was recorded for a replay.".to_string() };
    let studied = report.paper.iter().chain(&report.robustness).chain(&report.sweep).map(|r| r.seeds).max();
    /// The runs of one group of settings.
    #[derive(Default)]
    struct Group<'a> {
        name: &'a str,
        settings: Vec<&'a str>,
        controllers: Vec<&'a str>,
        seeds: Vec<u64>,
    }
    // Settings group by the words before their colon: "Sweep: 5 robots, ..." is a Sweep.
    let mut groups: Vec<Group> = Vec::new();
    for r in &report.replays {
        let name = r.setting.split(':').next().unwrap_or("").trim();
        let at = groups.iter().position(|g| g.name == name).unwrap_or_else(|| {
            groups.push(Group { name, ..Group::default() });
            groups.len() - 1
        });
        let g = &mut groups[at];
        if !g.settings.contains(&r.setting.as_str()) {
            g.settings.push(&r.setting);
        }
        if !g.controllers.contains(&r.meta.controller.as_str()) {
            g.controllers.push(&r.meta.controller);
        }
        if !g.seeds.contains(&r.meta.seed) {
            g.seeds.push(r.meta.seed);
        }
    }
    let mut parts = Vec::new();
    for Group { name: group, settings, controllers, mut seeds } in groups {
        seeds.sort_unstable();
        let settings = if settings.len() > 1 { format!(" ({} settings)", settings.len()) } else { String::new() };
        let of = match studied {
            Some(n) if seeds.len() < n as usize => format!(" of the {n} studied"),
            _ => String::new(),
        };
        let plural = if controllers.len() == 1 { "" } else { "s" };
        parts.push(format!("{group}{settings}: {} controller{plural} × {}{of}", controllers.len(), seed_list(&seeds)));
    }
    let mut steps: Vec<f64> = report.replays.iter().map(|r| f64::from(r.every) * r.meta.frame_dt).collect();
    steps.sort_by(f64::total_cmp);
    steps.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let step = match steps.as_slice() {
        [lo, .., hi] => format!("{lo:.2}–{hi:.2} s"),
        [one] => format!("{one:.2} s"),
        [] => "?".to_string(),
    };
    format!(
        "{} runs can be replayed: {}. To keep this page small, positions are kept every {step} (the simulator \
         recorded a frame every {} s) and interpolated in between; who drives, claims, is inhibited and observes \
         what is exact at every recorded frame.",
        report.replays.len(),
        parts.join("; "),
        first.meta.frame_dt
    )
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
        r##"<!DOCTYPE html>
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
<p class="verdict">{verdict} <a href="#summary">Summary</a> · <a href="#tables">tables</a> · <a href="#plots">plots</a></p>
<section class="replay">
<div class="stage">
<div class="runs">
<label>setting <select id="run-setting" aria-label="setting of the run to replay"></select></label>
<label>controller <select id="run-controller" aria-label="controller of the run to replay"></select></label>
<label>seed <select id="run-seed" aria-label="seed of the run to replay"></select></label>
</div>
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
<p class="note replay-note">{note}</p>
</div>
<aside class="panel">
<h3>Robots now</h3>
<table class="state"><thead><tr><th>robot</th><th>drive</th><th>claims</th><th>inhibited</th><th>observing</th></tr></thead>
<tbody id="robots-state"></tbody></table>
<h3>Targets now</h3>
<table class="state"><thead><tr><th>target</th><th>priority</th><th>observed by</th><th>claimed by</th></tr></thead>
<tbody id="targets-state"></tbody></table>
<h3>Run</h3>
<dl class="run" id="run-facts"></dl>
<h3>Legend</h3>
{LEGEND}
</aside>
</section>
"##,
        command = escape(&report.command),
        verdict = escape(&super::summary::claim(report)),
        note = escape(&replay_note(report)),
    );

    let _ = writeln!(
        out,
        "<section class=\"summary\" id=\"summary\">\n<h2>Summary</h2>\n<pre class=\"summary\">{}</pre>\n</section>",
        escape(super::summary_text(report).trim_end())
    );
    out.push_str("<section class=\"tables\" id=\"tables\">\n");
    for (i, (name, rows)) in tables::sections(report).into_iter().enumerate() {
        let _ = writeln!(out, "<h2>{}</h2>", escape(name));
        let table = tables::html(rows, escape);
        // The sweep is long; the plots summarise it, the table is there to look a number up.
        if i == 2 && rows.len() > 12 && report.cells.is_empty() {
            let _ = write!(out, "<details><summary>show all {} rows</summary>\n{table}</details>\n", rows.len());
        } else {
            out.push_str(&table);
        }
    }
    let _ = write!(out, "<h3>Columns</h3>\n{DEFINITIONS}\n</section>\n");

    out.push_str("<section class=\"plots\" id=\"plots\">\n<h2>Plots</h2>\n");
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

    let _ = writeln!(out, "<script type=\"application/json\" id=\"data\">{}</script>", script_json(&data(report)));
    for (i, replay) in report.replays.iter().enumerate() {
        let _ = writeln!(
            out,
            "<script type=\"application/json\" id=\"run-{i}\">{}</script>",
            script_json(&run_block(replay))
        );
    }
    let _ = write!(out, "<script>\n{REPLAY_JS}</script>\n</body>\n</html>\n");
    out
}
