//! The self-contained HTML file: the viewer page (`viewer/`), the recording
//! and three.js, all inline — it opens offline from disk in any current
//! browser, with nothing fetched at view time.
//!
//! # How three.js gets in
//!
//! three.js 0.187 ships as ES modules (`three.module.js` imports
//! `./three.core.js`; `OrbitControls.js` imports `three`), which cannot be
//! inlined as `<script type="module">` bodies that import each other. So the
//! three files (committed unmodified from the npm package, `vendor/three/`,
//! embedded with `include_str!`) travel gzipped and base64-encoded in inert
//! `<script type="application/octet-stream">` blocks. The page's bootstrap
//! un-gzips them with the browser's `DecompressionStream`, points the import
//! specifiers at blob URLs of each other, and `import()`s them. gzip also
//! shrinks the 2.2 MB of unminified library to 0.44 MB.
//!
//! The recording travels the same way ([`crate::encode`]); its JSON header
//! sits in a `<script type="application/json">` block.

use crate::encode::{FORMAT_VERSION, Section, base64, encode, gzip, gzip_base64};
use crate::recording::{
    BehaviourMeta, CageShape, FLAG_CHASED, FLAG_CHASING, FLAG_RESPAWNED, Info, ObstacleShape,
    Quant, Recording,
};
use deepfoids_env::TERM_NAMES;
use serde::Serialize;
use std::sync::LazyLock;

/// The three.js version embedded (its npm package, `vendor/three/package-lock.json`).
pub const THREE_VERSION: &str = "0.187.0";
/// `build/three.core.js` of the npm package.
pub const THREE_CORE: &str = include_str!("../vendor/three/three.core.js");
/// `build/three.module.js` of the npm package.
pub const THREE_MODULE: &str = include_str!("../vendor/three/three.module.js");
/// `examples/jsm/controls/OrbitControls.js` of the npm package.
pub const ORBIT_CONTROLS: &str = include_str!("../vendor/three/OrbitControls.js");
/// three.js' MIT licence, shown in the viewer's "About" box.
pub const THREE_LICENSE: &str = include_str!("../vendor/three/LICENSE");
/// The import specifier `three.module.js` uses for the core (rewritten at view time).
pub const CORE_SPECIFIER: &str = "'./three.core.js'";
/// The import specifier `OrbitControls.js` uses for three (rewritten at view time).
pub const THREE_SPECIFIER: &str = "'three'";

const TEMPLATE: &str = include_str!("../viewer/viewer.html");
const VIEWER_JS: &str = include_str!("../viewer/viewer.js");
const VIEWER_CSS: &str = include_str!("../viewer/viewer.css");

/// The library blocks, compressed once per process.
static LIBRARY: LazyLock<[String; 3]> = LazyLock::new(|| {
    [
        gzip_base64(THREE_CORE.as_bytes()),
        gzip_base64(THREE_MODULE.as_bytes()),
        gzip_base64(ORBIT_CONTROLS.as_bytes()),
    ]
});

/// The JSON header the viewer reads first.
#[derive(Serialize)]
struct Header<'a> {
    format: u32,
    generator: String,
    three: &'static str,
    info: &'a Info,
    cage: &'a CageShape,
    obstacles: &'a [ObstacleShape],
    behaviours: &'a [BehaviourMeta],
    fish: usize,
    frames: usize,
    quant: Quant,
    term_names: [&'static str; deepfoids_env::N_TERMS],
    has_terms: bool,
    has_chases: bool,
    flag_bits: FlagBits,
    sections: &'a [Section],
}

#[derive(Serialize)]
struct FlagBits {
    respawned: u8,
    chasing: u8,
    chased: u8,
}

/// Byte counts of a written page.
#[derive(Clone, Copy, Debug)]
pub struct PageSize {
    /// The recording's sections before gzip.
    pub data_raw: usize,
    /// The recording gzipped.
    pub data_gzip: usize,
    /// The recording as carried in the page (gzip, then base64).
    pub data: usize,
    /// three.js as carried in the page.
    pub library: usize,
    /// The whole page.
    pub total: usize,
}

/// The HTML page replaying `rec`, and its size split.
pub fn page(rec: &Recording) -> (String, PageSize) {
    let enc = encode(rec);
    let header = Header {
        format: FORMAT_VERSION,
        generator: format!("deepfoids {}", env!("CARGO_PKG_VERSION")),
        three: THREE_VERSION,
        info: &rec.info,
        cage: &rec.cage,
        obstacles: &rec.obstacles,
        behaviours: &rec.behaviours,
        fish: rec.fish,
        frames: rec.frames(),
        quant: rec.quant,
        term_names: TERM_NAMES,
        has_terms: !rec.terms.is_empty(),
        has_chases: rec.has_chases,
        flag_bits: FlagBits {
            respawned: FLAG_RESPAWNED,
            chasing: FLAG_CHASING,
            chased: FLAG_CHASED,
        },
        sections: &enc.sections,
    };
    let json = serde_json::to_string(&header).expect("the header serialises");
    let zipped = gzip(&enc.bytes);
    let data = base64(&zipped);
    let lib = &*LIBRARY;
    let html = fill(
        TEMPLATE,
        &[
            ("TITLE", &escape_html(&rec.info.title)),
            ("CSS", VIEWER_CSS),
            ("LICENSE", &escape_html(THREE_LICENSE)),
            ("THREE_VERSION", THREE_VERSION),
            ("META", &script_json(&json)),
            ("DATA", &data),
            ("THREE_CORE", &lib[0]),
            ("THREE_MODULE", &lib[1]),
            ("ORBIT_CONTROLS", &lib[2]),
            ("VIEWER_JS", VIEWER_JS),
        ],
    );
    let size = PageSize {
        data_raw: enc.bytes.len(),
        data_gzip: zipped.len(),
        data: data.len(),
        library: lib.iter().map(String::len).sum(),
        total: html.len(),
    };
    (html, size)
}

/// Replace each `{{KEY}}` of `template` by its value. Values are not scanned
/// again, so a value holding `{{…}}` is left as it is.
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let extra: usize = values.iter().map(|(_, v)| v.len()).sum();
    let mut out = String::with_capacity(template.len() + extra);
    let mut rest = template;
    while let Some(start) = rest.find("{{") {
        let Some(len) = rest[start + 2..].find("}}") else {
            break;
        };
        let key = &rest[start + 2..start + 2 + len];
        let value = values
            .iter()
            .find(|(k, _)| *k == key)
            .unwrap_or_else(|| panic!("viewer.html names an unknown slot {{{{{key}}}}}"));
        out.push_str(&rest[..start]);
        out.push_str(value.1);
        rest = &rest[start + 2 + len + 2..];
    }
    out.push_str(rest);
    out
}

/// JSON that is safe inside a `<script>` block: `<` only occurs inside JSON
/// strings, where `\u003c` means the same.
fn script_json(json: &str) -> String {
    json.replace('<', "\\u003c")
}

fn escape_html(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recording::tests::env;
    use crate::recording::{EnvRecorder, Recording};
    use base64::Engine;
    use deepfoids_env::policy::action_buffers;
    use deepfoids_env::{Policy, RandomPolicy};
    use std::io::Read;

    /// The text of `<script … id="{id}">…</script>`.
    fn block<'a>(html: &'a str, id: &str) -> &'a str {
        let start = html.find(&format!("id=\"{id}\">")).unwrap() + id.len() + 6;
        let len = html[start..].find("</script>").unwrap();
        &html[start..start + len]
    }

    fn gunzip_base64(b64: &str) -> Vec<u8> {
        let zipped = base64::engine::general_purpose::STANDARD
            .decode(b64)
            .unwrap();
        let mut out = vec![];
        flate2::read::GzDecoder::new(&zipped[..])
            .read_to_end(&mut out)
            .unwrap();
        out
    }

    fn recording() -> Recording {
        let mut env = env("seabream_50", 3);
        let mut policy = RandomPolicy { seed: 3 };
        let mut actions = action_buffers(&env);
        let info = Info {
            title: "seabream_50 · random <&> seed 3".into(),
            scene: "seabream_50".into(),
            description: "</script><!-- a scene".into(),
            policy: "random".into(),
            seed: 3,
            phase: "pretrain".into(),
            source: "test".into(),
            notes: vec![],
        };
        let mut rec = EnvRecorder::new(&env, info, 5.0).unwrap();
        for _ in 0..30 {
            policy.act(&env, &mut actions).unwrap();
            env.step(&actions).unwrap();
            rec.observe(&env);
        }
        rec.finish([(0.0, 0.2, 0.7), (0.1, 0.3, 0.6)])
    }

    /// Decode the page as viewer.js does (header, gunzip, byte planes,
    /// position sums, term-major terms) and get the recording back bit for
    /// bit; the library blocks are the vendored files; nothing is fetched.
    #[test]
    fn the_page_carries_the_recording_and_three_js() {
        let rec = recording();
        let (html, size) = page(&rec);
        assert_eq!(size.total, html.len());
        assert!(!html.contains("http://") && !html.contains("https://"));
        assert!(!html.contains(" src=") && !html.contains(" href="));
        assert!(html.contains("<title>seabream_50 · random &lt;&amp;&gt; seed 3</title>"));
        assert_eq!(
            gunzip_base64(block(&html, "lib-three-core")),
            THREE_CORE.as_bytes()
        );
        assert_eq!(
            gunzip_base64(block(&html, "lib-three-module")),
            THREE_MODULE.as_bytes()
        );
        assert_eq!(
            gunzip_base64(block(&html, "lib-orbit-controls")),
            ORBIT_CONTROLS.as_bytes()
        );

        let meta: serde_json::Value = serde_json::from_str(block(&html, "replay-meta")).unwrap();
        assert_eq!(meta["format"], 1);
        assert_eq!(meta["info"]["description"], "</script><!-- a scene");
        assert_eq!(meta["fish"], 50);
        assert_eq!(meta["frames"], 16);
        assert_eq!(meta["has_chases"], true);
        assert_eq!(meta["cage"]["outline"].as_array().unwrap().len(), 4);
        let packed = gunzip_base64(block(&html, "replay-data"));
        let section = |name: &str| -> (Vec<u8>, usize) {
            let s = meta["sections"]
                .as_array()
                .unwrap()
                .iter()
                .find(|s| s["name"] == name)
                .unwrap();
            let size = match s["type"].as_str().unwrap() {
                "u8" => 1,
                "u16" | "i16" => 2,
                _ => 4,
            };
            let (off, n) = (
                s["offset"].as_u64().unwrap() as usize,
                s["length"].as_u64().unwrap() as usize,
            );
            assert_eq!(off % 8, 0);
            let mut bytes = vec![0; n * size];
            for j in 0..size {
                for i in 0..n {
                    bytes[i * size + j] = packed[off + j * n + i];
                }
            }
            (bytes, n)
        };
        let u16s = |name: &str| -> Vec<u16> {
            let (b, _) = section(name);
            b.chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]))
                .collect()
        };
        let mut pos = u16s("position_delta");
        for k in 3 * rec.fish..pos.len() {
            pos[k] = pos[k].wrapping_add(pos[k - 3 * rec.fish]);
        }
        assert_eq!(pos, rec.position);
        assert_eq!(u16s("yaw"), rec.yaw);
        assert_eq!(u16s("speed"), rec.speed);
        let terms = u16s("terms");
        let (f, n) = (rec.frames(), rec.fish);
        for k in 0..f * n {
            for t in 0..deepfoids_env::N_TERMS {
                assert_eq!(
                    terms[(t * f + k / n) * n + k % n],
                    rec.terms[k * deepfoids_env::N_TERMS + t]
                );
            }
        }
        assert_eq!(section("flags").0, rec.flags);
        let (bl, _) = section("bl");
        let bl: Vec<f32> = bl
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        assert_eq!(bl, rec.bl);
        assert_eq!(section("curve_state").0, rec.curves.state);
        let (pairs, n_pairs) = section("chase_pairs");
        assert_eq!(n_pairs, 2 * rec.chase_pairs.len());
        assert!(n_pairs > 0);
        assert_eq!(
            u32::from_le_bytes(pairs[..4].try_into().unwrap()),
            rec.chase_pairs[0][0]
        );
    }

    #[test]
    fn fill_replaces_slots_once() {
        let t = "a{{X}}b{{Y}}c{{X}}";
        assert_eq!(fill(t, &[("X", "{{Y}}"), ("Y", "2")]), "a{{Y}}b2c{{Y}}");
    }

    #[test]
    fn script_json_has_no_tags() {
        let j = serde_json::to_string(&"</script><!--").unwrap();
        let s = script_json(&j);
        assert!(!s.contains('<'));
        assert_eq!(serde_json::from_str::<String>(&s).unwrap(), "</script><!--");
    }

    /// The bootstrap rewrites these specifiers; a three.js update that changes
    /// them must fail here, not in a user's browser.
    #[test]
    fn vendored_three_imports_what_the_bootstrap_rewrites() {
        assert_eq!(THREE_MODULE.matches(CORE_SPECIFIER).count(), 2);
        assert!(!THREE_MODULE.contains("from 'three'"));
        assert_eq!(
            ORBIT_CONTROLS
                .matches(&format!("from {THREE_SPECIFIER}"))
                .count(),
            1
        );
        assert!(!THREE_CORE.contains(" from '"));
        assert!(THREE_CORE.contains(&format!("REVISION = '{}'", &THREE_VERSION[2..5])));
        let viewer = VIEWER_JS;
        assert!(viewer.contains(CORE_SPECIFIER) && viewer.contains(THREE_SPECIFIER));
    }

    /// Inline code must not end its `<script>` early.
    #[test]
    fn inline_code_cannot_close_its_script_block() {
        for (name, s) in [("viewer.js", VIEWER_JS), ("viewer.css", VIEWER_CSS)] {
            let l = s.to_lowercase();
            assert!(
                !l.contains("</script") && !l.contains("<!--") && !l.contains("</style"),
                "{name}"
            );
        }
    }
}
