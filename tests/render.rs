//! Integration tests of `deepfoids render`: the dataset's files and formats,
//! and continuing an interrupted render.

mod support;

use std::path::{Path, PathBuf};
use std::process::Output;
use support::{deepfoids, fails, succeeds};

fn render(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "render",
        "--scene",
        "seabream_default",
        "--policy",
        "foids",
        "--frames",
        "4",
        "--width",
        "160",
        "--height",
        "96",
        "--warmup",
        "1",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    deepfoids(&args)
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// A side-camera render of 10 seabream: every file of the dataset exists,
/// YOLO boxes are normalised, COCO counts match the YOLO lines, and the mask
/// is a 16-bit PNG whose ids match the labelled fish. The dataset stays at
/// target/render-check for `.ci/check_coco.py` (pycocotools).
#[test]
fn render_writes_a_yolo_and_coco_dataset() {
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/render-check");
    let _ = std::fs::remove_dir_all(&out);
    let o = render(&out, &["--camera", "side"]);
    succeeds(&o);
    for f in ["data.yaml", "annotations.json", "scene.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let coco = json(&out.join("annotations.json"));
    assert_eq!(coco["images"].as_array().unwrap().len(), 4);
    assert_eq!(coco["categories"][0]["name"], "seabream");
    let mut yolo_lines = 0;
    let mut yolo_lines_in_frames = 0;
    for i in 0..4 {
        let name = format!("frame_{i:06}");
        assert!(out.join(format!("images/{name}.jpg")).is_file());
        let labels = std::fs::read_to_string(out.join(format!("labels/{name}.txt"))).unwrap();
        for line in labels.lines() {
            let v: Vec<f64> = line.split(' ').map(|s| s.parse().unwrap()).collect();
            assert_eq!(v.len(), 5);
            assert!(v[1..].iter().all(|x| (0.0..=1.0).contains(x)), "{line}");
            yolo_lines += 1;
        }
        let mask = image::open(out.join(format!("masks/{name}.png"))).unwrap();
        let mask = mask.as_luma16().expect("a 16-bit mask").clone();
        assert_eq!(mask.dimensions(), (160, 96));
        let frame = json(&out.join(format!("frames/{name}.json")));
        let fish = frame["fish"].as_array().unwrap();
        for f in fish {
            let id = f["label"]["fish"].as_u64().unwrap() as u16 + 1;
            let n = mask.pixels().filter(|p| p.0[0] == id).count() as u64;
            assert_eq!(n, f["label"]["visible_pixels"].as_u64().unwrap());
        }
        let count = |key: &str, pred: &dyn Fn(&serde_json::Value) -> bool| {
            assert_eq!(
                frame[key].as_u64().unwrap() as usize,
                fish.iter().filter(|f| pred(&f["label"])).count(),
                "{key}"
            );
        };
        count("visible_fish", &|l| l["detectable"] == true);
        count("in_view_fish", &|l| {
            l["visible_pixels"].as_u64().unwrap() > 0
        });
        // Detectable: visible pixels and the default least contrast, 0.03.
        for f in fish {
            let l = &f["label"];
            let want = l["visible_pixels"].as_u64().unwrap() > 0
                && l["contrast"].as_f64().unwrap() >= 0.03 - 1e-6;
            assert_eq!(l["detectable"] == true, want, "{l}");
        }
        yolo_lines_in_frames += fish
            .iter()
            .filter(|f| f["label"]["detectable"] == true)
            .count();
    }
    assert!(yolo_lines > 0, "no fish seen by the side camera");
    assert_eq!(yolo_lines, yolo_lines_in_frames);
    assert_eq!(coco["annotations"].as_array().unwrap().len(), yolo_lines);
    let yaml = std::fs::read_to_string(out.join("data.yaml")).unwrap();
    // One clip: nothing held out, and the file says so.
    assert!(
        yaml.contains("train: train.txt")
            && yaml.contains("val: train.txt")
            && yaml.contains("0: seabream"),
        "{yaml}"
    );
    let train = std::fs::read_to_string(out.join("train.txt")).unwrap();
    assert_eq!(train.lines().count(), 4);
    assert!(train.starts_with("./images/frame_000000.jpg"), "{train}");
    let counts = std::fs::read_to_string(out.join("counts.csv")).unwrap();
    assert_eq!(counts.lines().count(), 5, "{counts}");
    assert!(coco["images"][0]["lens"]["model"] == "pinhole");
}

/// An interrupted render continues: a frame removed afterwards is rendered
/// again, identical (the clip is re-simulated from its seed), and the others
/// are kept. Different arguments in the same folder are refused.
#[test]
fn interrupted_render_continues_identically() {
    let out = std::env::temp_dir().join(format!("deepfoids-render-resume-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let args = ["--randomize", "--clip-frames", "2", "--seed", "3"];
    let o = render(&out, &args);
    succeeds(&o);
    let label = out.join("labels/frame_000003.txt");
    let before = std::fs::read_to_string(&label).unwrap();
    let frame_json = std::fs::read_to_string(out.join("frames/frame_000003.json")).unwrap();
    std::fs::remove_file(out.join("frames/frame_000003.json")).unwrap();
    std::fs::remove_file(&label).unwrap();
    let kept = std::fs::metadata(out.join("frames/frame_000000.json"))
        .unwrap()
        .modified()
        .unwrap();
    let t = succeeds(&render(&out, &args));
    assert!(t.contains("1 rendered now, 3 kept"), "{t}");
    assert_eq!(std::fs::read_to_string(&label).unwrap(), before);
    assert_eq!(
        std::fs::read_to_string(out.join("frames/frame_000003.json")).unwrap(),
        frame_json
    );
    let again = std::fs::metadata(out.join("frames/frame_000000.json"))
        .unwrap()
        .modified()
        .unwrap();
    assert_eq!(kept, again);
    // Two clips with their own draws.
    let scene = json(&out.join("scene.json"));
    let clips = scene["clips"].as_array().unwrap();
    assert_eq!(clips.len(), 2);
    assert_ne!(clips[0]["water"], clips[1]["water"]);
    // Split by clip: clip 0 trains, clip 1 (frames 2 and 3) is held out, in
    // data.yaml's lists and in the per-split COCO files alike.
    let yaml = std::fs::read_to_string(out.join("data.yaml")).unwrap();
    assert!(yaml.contains("val: val.txt"), "{yaml}");
    let val = std::fs::read_to_string(out.join("val.txt")).unwrap();
    assert_eq!(
        val,
        "./images/frame_000002.jpg\n./images/frame_000003.jpg\n"
    );
    let coco_val = json(&out.join("annotations_val.json"));
    let coco_train = json(&out.join("annotations_train.json"));
    let clips_of = |c: &serde_json::Value| -> Vec<u64> {
        c["images"]
            .as_array()
            .unwrap()
            .iter()
            .map(|i| i["clip"].as_u64().unwrap())
            .collect()
    };
    assert_eq!(clips_of(&coco_val), vec![1, 1]);
    assert_eq!(clips_of(&coco_train), vec![0, 0]);
    assert_eq!(coco_val["info"]["split"], "val");
    let all = json(&out.join("annotations.json"));
    assert_eq!(
        coco_val["annotations"].as_array().unwrap().len()
            + coco_train["annotations"].as_array().unwrap().len(),
        all["annotations"].as_array().unwrap().len()
    );
    fails(
        &render(&out, &["--randomize", "--clip-frames", "2", "--seed", "4"]),
        "other arguments",
    );
    let _ = std::fs::remove_dir_all(&out);
    // A policy of another species is refused before the folder is made.
    let mismatch = out.with_extension("mismatch");
    let t = fails(
        &deepfoids(&[
            "render",
            "--scene",
            "seabream_default",
            "--policy",
            "pretrained:coho",
            "--frames",
            "2",
            "--out",
            mismatch.to_str().unwrap(),
        ]),
        "no policy for behaviour seabream_regular",
    );
    assert!(!mismatch.exists(), "{t}");
}
