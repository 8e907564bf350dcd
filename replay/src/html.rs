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

use crate::encode::{FORMAT_VERSION, Section, encode, gzip_base64};
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
    /// The recording as carried in the page (gzip + base64).
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
    let data = gzip_base64(&enc.bytes);
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
