//! Writing a dataset: per frame an image (`images/`), a YOLO label file
//! (`labels/`, Ultralytics format: `class cx cy w h`, normalised, one line per
//! visible fish, box of the visible silhouette), a 16-bit instance mask
//! (`masks/`, pixel value = fish index + 1, 0 = no fish) and a JSON file with
//! every label (`frames/`: both 2D boxes, 3D box corners in world and camera
//! coordinates, visibility, truncation, species, size class, RLE
//! segmentation, the frame's visible-fish count and conditions). At the end,
//! `annotations.json` (COCO, every frame, each image with its `split`),
//! `annotations_train.json` / `annotations_val.json`, `train.txt` / `val.txt`
//! (the split by clip, never by frame), `data.yaml` naming them, and
//! `counts.csv` (visible fish per frame) are assembled from the frame files;
//! `scene.json` holds every parameter.
//!
//! Every file is written atomically, the frame JSON last: a frame whose JSON
//! exists is complete, which is how an interrupted render continues.

use crate::render::{FishLabel, Frame};
use deepfoids_io::write_atomic;
use rayon::prelude::*;
use serde::Serialize;
use serde_json::{Value, json};
use std::io::Cursor;
use std::path::{Path, PathBuf};

/// Errors of the dataset writer.
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// The I/O error is part of the message, not a `source`: a chain says it once.
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("cannot encode {path}: {message}")]
    Encode { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
}

/// `value` as JSON text (compact, or pretty), written atomically to `path`.
fn write_json(path: &Path, value: &impl Serialize, pretty: bool) -> Result<(), DatasetError> {
    let text = if pretty {
        serde_json::to_string_pretty(value)
    } else {
        serde_json::to_string(value)
    }
    .map_err(|e| DatasetError::Encode {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    write_atomic(path, text.as_bytes()).map_err(io(path))
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |error| DatasetError::Io {
        path: path.to_path_buf(),
        error,
    }
}

/// A frame's JSON file, parsed.
fn read_json(path: &Path) -> Result<Value, DatasetError> {
    let bytes = std::fs::read(path).map_err(io(path))?;
    serde_json::from_slice(&bytes).map_err(|e| DatasetError::Invalid {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Image file format.
/// Quality of the JPEG images (4:2:0 chroma, standard tables).
const JPEG_QUALITY: u8 = 92;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageFormat {
    /// JPEG, quality 92 (default: a tenth of the PNG's size).
    Jpg,
    /// Lossless PNG.
    Png,
}

impl std::str::FromStr for ImageFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "jpg" | "jpeg" => Ok(Self::Jpg),
            "png" => Ok(Self::Png),
            o => Err(format!("unknown image format `{o}`; allowed: jpg, png")),
        }
    }
}

impl ImageFormat {
    pub fn ext(&self) -> &'static str {
        match self {
            Self::Jpg => "jpg",
            Self::Png => "png",
        }
    }
}

/// A dataset folder.
#[derive(Clone, Debug)]
pub struct Dataset {
    pub dir: PathBuf,
    pub format: ImageFormat,
    /// Category names, index = YOLO class = COCO category id − 1.
    pub classes: Vec<String>,
    /// Size class of each behaviour (for the labels).
    pub size_classes: Vec<String>,
}

/// What a frame adds to its labels besides the fish.
#[derive(Clone, Debug, Serialize)]
pub struct FrameMeta {
    pub clip: usize,
    /// Simulated time since the clip's start (s).
    pub time: f64,
    /// Local clock time (hours).
    pub clock_hours: f64,
    pub sun_elevation_deg: f32,
    pub camera: crate::camera::Camera,
    /// `train` or `val`: the split of the frame's clip (never split inside a clip).
    pub split: Split,
    /// Times the clip's water was redrawn because nothing was visible (0 at first).
    pub water_attempt: u32,
}

/// A frame's JSON (`frames/`).
#[derive(Serialize)]
struct FrameEntry<'a> {
    frame: usize,
    file_name: String,
    mask: String,
    width: u32,
    height: u32,
    visible_fish: usize,
    in_view_fish: usize,
    exposure_gain: f32,
    meta: &'a FrameMeta,
    fish: Vec<FishEntry<'a>>,
}

/// A fish in its frame's JSON.
#[derive(Serialize)]
struct FishEntry<'a> {
    label: &'a FishLabel,
    species: Option<&'a String>,
    size_class: Option<&'a String>,
    /// COCO's compressed RLE of the visible pixels.
    segmentation: Option<Segmentation>,
}

#[derive(Serialize)]
struct Segmentation {
    /// `[height, width]`.
    size: [u32; 2],
    counts: String,
}

/// Writes a dataset's frames one behind their rendering: [`FrameWriter::next`]
/// renders a frame while the previous one is encoded and written
/// (`rayon::join`), so the writing's serial parts (label JSON, files) run
/// beside the next frame's rendering instead of after it. Frames are written
/// in order; one not yet written when a run stops is rendered again when it
/// continues (its JSON, written last, is missing).
pub struct FrameWriter<'a> {
    dataset: &'a Dataset,
    behaviour_of: &'a [u16],
    pending: Option<(usize, Frame, FrameMeta)>,
}

impl<'a> FrameWriter<'a> {
    /// `behaviour_of[fish]` names each fish's behaviour (its size class).
    pub fn new(dataset: &'a Dataset, behaviour_of: &'a [u16]) -> Self {
        Self {
            dataset,
            behaviour_of,
            pending: None,
        }
    }

    /// Render frame `i` with `render` while the previous frame is written;
    /// returns frame `i`'s visible-fish count.
    pub fn next(
        &mut self,
        i: usize,
        meta: FrameMeta,
        render: impl FnOnce() -> Frame + Send,
    ) -> Result<usize, DatasetError> {
        let pending = self.pending.take();
        let (frame, written) = rayon::join(render, || self.write(pending));
        written?;
        let visible = frame.visible_count();
        self.pending = Some((i, frame, meta));
        Ok(visible)
    }

    /// Write the last frame.
    pub fn finish(mut self) -> Result<(), DatasetError> {
        let pending = self.pending.take();
        self.write(pending)
    }

    fn write(&self, pending: Option<(usize, Frame, FrameMeta)>) -> Result<(), DatasetError> {
        pending.map_or(Ok(()), |(i, frame, meta)| {
            self.dataset
                .write_frame(i, &frame, self.behaviour_of, &meta)
        })
    }
}

/// Which split a clip belongs to. Neighbouring frames of a clip are nearly
/// identical, so the split is by clip, never by frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    Train,
    Val,
}

impl Split {
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Train => "train",
            Self::Val => "val",
        }
    }

    /// The split of clip `clip` of `clips` with a share `val_fraction` of
    /// clips held out: clip `c` is a validation clip when `(c + 1)·f` passes
    /// a whole number (so they are spread evenly: every 5th for 0.2), and the
    /// last clip is one if that picked none of two or more. A single clip is
    /// always `train` (there is nothing to hold out without leaking frames).
    pub fn of_clip(clip: usize, clips: usize, val_fraction: f64) -> Self {
        if clips < 2 || val_fraction <= 0.0 {
            return Self::Train;
        }
        let f = val_fraction.min(1.0);
        let val = |c: usize| ((c + 1) as f64 * f).floor() > (c as f64 * f).floor();
        let any = (0..clips).any(val);
        if val(clip) || (!any && clip + 1 == clips) {
            Self::Val
        } else {
            Self::Train
        }
    }
}

impl Dataset {
    pub fn new(
        dir: &Path,
        format: ImageFormat,
        classes: Vec<String>,
        size_classes: Vec<String>,
    ) -> Self {
        Self {
            dir: dir.to_path_buf(),
            format,
            classes,
            size_classes,
        }
    }

    fn name(i: usize) -> String {
        format!("frame_{i:06}")
    }

    pub fn image_path(&self, i: usize) -> PathBuf {
        self.dir
            .join("images")
            .join(format!("{}.{}", Self::name(i), self.format.ext()))
    }
    pub fn label_path(&self, i: usize) -> PathBuf {
        self.dir
            .join("labels")
            .join(format!("{}.txt", Self::name(i)))
    }
    pub fn mask_path(&self, i: usize) -> PathBuf {
        self.dir
            .join("masks")
            .join(format!("{}.png", Self::name(i)))
    }
    pub fn frame_json_path(&self, i: usize) -> PathBuf {
        self.dir
            .join("frames")
            .join(format!("{}.json", Self::name(i)))
    }

    /// Whether frame `i` was completely written (its JSON comes last).
    pub fn frame_done(&self, i: usize) -> bool {
        self.frame_json_path(i).is_file()
            && self.image_path(i).is_file()
            && self.label_path(i).is_file()
            && self.mask_path(i).is_file()
    }

    /// Frame `i`'s visible-fish count and its clip's water attempt, from its JSON.
    pub fn frame_meta(&self, i: usize) -> Result<(usize, u32), DatasetError> {
        let p = self.frame_json_path(i);
        let v = read_json(&p)?;
        Ok((
            v["visible_fish"].as_u64().unwrap_or(0) as usize,
            v["meta"]["water_attempt"].as_u64().unwrap_or(0) as u32,
        ))
    }

    /// Write `scene.json`, or check that an existing one describes the same
    /// render (so a continued render does not mix two datasets).
    pub fn write_or_check_scene(&self, params: &Value, key: &Value) -> Result<(), DatasetError> {
        let path = self.dir.join("scene.json");
        if path.is_file() {
            let old: Value = serde_json::from_slice(&std::fs::read(&path).map_err(io(&path))?)
                .map_err(|e| DatasetError::Invalid {
                    path: path.clone(),
                    message: e.to_string(),
                })?;
            if old.get("request") != Some(key) {
                return Err(DatasetError::Invalid {
                    path,
                    message: "this folder holds a render with other arguments; use the same arguments to continue it, or another --out".into(),
                });
            }
            return Ok(());
        }
        let mut v = params.clone();
        v["request"] = key.clone();
        write_json(&path, &v, true)
    }

    /// Write frame `i`: image, mask, YOLO labels, then the frame JSON.
    pub fn write_frame(
        &self,
        i: usize,
        frame: &Frame,
        behaviour_of: &[u16],
        meta: &FrameMeta,
    ) -> Result<(), DatasetError> {
        let (img, mask) = rayon::join(|| self.encode_image(i, frame), || encode_mask(frame));
        let img = img?;
        let mask = mask.map_err(|message| DatasetError::Encode {
            path: self.mask_path(i),
            message,
        })?;
        let p = self.image_path(i);
        write_atomic(&p, &img).map_err(io(&p))?;
        let p = self.mask_path(i);
        write_atomic(&p, &mask).map_err(io(&p))?;
        let p = self.label_path(i);
        write_atomic(&p, yolo_labels(frame).as_bytes()).map_err(io(&p))?;
        // Serialised straight from the labels (a `Value` would widen each f32
        // to f64 and print 1.613 as 1.6130000352859497).
        let entry = FrameEntry {
            frame: i,
            file_name: format!("images/{}.{}", Self::name(i), self.format.ext()),
            mask: format!("masks/{}.png", Self::name(i)),
            width: frame.width,
            height: frame.height,
            visible_fish: frame.visible_count(),
            in_view_fish: frame.in_view_count(),
            exposure_gain: frame.gain,
            meta,
            fish: frame
                .fish
                .par_iter()
                .map(|f| self.fish_entry(f, frame, behaviour_of))
                .collect(),
        };
        let p = self.frame_json_path(i);
        write_json(&p, &entry, false)
    }

    fn fish_entry<'a>(
        &'a self,
        f: &'a FishLabel,
        frame: &Frame,
        behaviour_of: &[u16],
    ) -> FishEntry<'a> {
        let b = behaviour_of.get(f.fish).copied().unwrap_or(0) as usize;
        FishEntry {
            label: f,
            species: self.classes.get(f.species as usize),
            size_class: self.size_classes.get(b),
            segmentation: f.box_visible.map(|bx| Segmentation {
                size: [frame.height, frame.width],
                counts: rle_string(&rle_counts(frame, (f.fish + 1) as u16, bx)),
            }),
        }
    }

    fn encode_image(&self, i: usize, frame: &Frame) -> Result<Vec<u8>, DatasetError> {
        let mut buf = Vec::new();
        let res = match self.format {
            ImageFormat::Jpg => jpeg_encoder::Encoder::new(&mut buf, JPEG_QUALITY)
                .encode(
                    &frame.rgb,
                    frame.width as u16,
                    frame.height as u16,
                    jpeg_encoder::ColorType::Rgb,
                )
                .map_err(|e| e.to_string()),
            ImageFormat::Png => image::ImageEncoder::write_image(
                image::codecs::png::PngEncoder::new_with_quality(
                    Cursor::new(&mut buf),
                    image::codecs::png::CompressionType::Fast,
                    image::codecs::png::FilterType::Adaptive,
                ),
                &frame.rgb,
                frame.width,
                frame.height,
                image::ExtendedColorType::Rgb8,
            )
            .map_err(|e| e.to_string()),
        };
        res.map_err(|message| DatasetError::Encode {
            path: self.image_path(i),
            message,
        })?;
        Ok(buf)
    }

    /// Assemble `annotations.json` (COCO) and `data.yaml` from frames `0..n`.
    /// Returns the number of annotations.
    pub fn finish(&self, n: usize) -> Result<usize, DatasetError> {
        let mut images = Vec::with_capacity(n);
        let mut anns = Vec::new();
        let mut counts = String::from("frame,clip,split,visible_fish,in_view_fish\n");
        for i in 0..n {
            let p = self.frame_json_path(i);
            let v = read_json(&p)?;
            let split = v["meta"]["split"].as_str().unwrap_or("train").to_string();
            counts.push_str(&format!(
                "{i},{},{split},{},{}\n",
                v["meta"]["clip"], v["visible_fish"], v["in_view_fish"]
            ));
            images.push(json!({
                "id": i + 1,
                "file_name": v["file_name"],
                "width": v["width"],
                "height": v["height"],
                "visible_fish": v["visible_fish"],
                "clip": v["meta"]["clip"],
                "time": v["meta"]["time"],
                "split": split,
                "lens": v["meta"]["camera"]["lens"],
            }));
            for f in v["fish"].as_array().into_iter().flatten() {
                let l = &f["label"];
                // Detectable fish have visible pixels, hence a visible box.
                let (Some(true), Some(bx)) =
                    (l["detectable"].as_bool(), l["box_visible"].as_array())
                else {
                    continue;
                };
                let b: Vec<f64> = bx.iter().filter_map(|x| x.as_f64()).collect();
                let full: Vec<f64> = l["box_full"]
                    .as_array()
                    .map(|a| a.iter().filter_map(|x| x.as_f64()).collect())
                    .unwrap_or_default();
                anns.push(json!({
                    "id": anns.len() + 1,
                    "image_id": i + 1,
                    "category_id": l["species"].as_u64().unwrap_or(0) + 1,
                    "bbox": [b[0], b[1], b[2] - b[0], b[3] - b[1]],
                    "area": l["visible_pixels"],
                    "iscrowd": 0,
                    "segmentation": f["segmentation"],
                    "fish_id": l["fish"],
                    "size_class": f["size_class"],
                    "visibility": l["visibility"],
                    "truncated": l["truncated"],
                    "bbox_full": [full[0], full[1], full[2] - full[0], full[3] - full[1]],
                    "bbox3d_world": l["box3d_world"],
                    "bbox3d_camera": l["box3d_camera"],
                    "distance": l["distance"],
                }));
            }
        }
        let categories: Vec<Value> = self
            .classes
            .iter()
            .enumerate()
            .map(|(k, c)| json!({"id": k + 1, "name": c, "supercategory": "fish"}))
            .collect();
        let n_anns = anns.len();
        let coco = |images: Vec<Value>, anns: Vec<Value>, split: &str| {
            json!({
                "info": {"description": format!("DeepFoids synthetic fish dataset ({split})"), "version": "1.0", "split": split},
                "licenses": [],
                "images": images,
                "annotations": anns,
                "categories": categories,
            })
        };
        let write = |name: &str, v: &Value| write_json(&self.dir.join(name), v, false);
        // One COCO file per split (image and annotation ids kept), and all.
        let mut lists = String::new();
        let mut val_frames = 0;
        for split in ["train", "val"] {
            let ids: std::collections::HashSet<u64> = images
                .iter()
                .filter(|im| im["split"] == split)
                .filter_map(|im| im["id"].as_u64())
                .collect();
            let im: Vec<Value> = images
                .iter()
                .filter(|im| im["split"] == split)
                .cloned()
                .collect();
            let list: String = im
                .iter()
                .map(|im| format!("./{}\n", im["file_name"].as_str().unwrap_or_default()))
                .collect();
            let p = self.dir.join(format!("{split}.txt"));
            write_atomic(&p, list.as_bytes()).map_err(io(&p))?;
            lists.push_str(&format!("# {split}: {} frames\n", im.len()));
            if split == "val" {
                val_frames = im.len();
            }
            let an: Vec<Value> = anns
                .iter()
                .filter(|a| a["image_id"].as_u64().is_some_and(|i| ids.contains(&i)))
                .cloned()
                .collect();
            write(&format!("annotations_{split}.json"), &coco(im, an, split))?;
        }
        write("annotations.json", &coco(images, anns, "all"))?;
        let p = self.dir.join("counts.csv");
        write_atomic(&p, counts.as_bytes()).map_err(io(&p))?;
        let abs = std::fs::canonicalize(&self.dir).unwrap_or_else(|_| self.dir.clone());
        let mut yaml = format!(
            "# Ultralytics YOLO dataset written by `deepfoids render`, split by clip\n# (never by frame: neighbouring frames are nearly identical).\n{lists}path: {}\ntrain: train.txt\n{}names:\n",
            abs.display(),
            if val_frames > 0 {
                "val: val.txt\n"
            } else {
                "# One clip: nothing can be held out without leaking frames (render\n# several clips, e.g. with --randomize, for a split).\nval: train.txt\n"
            }
        );
        for (k, c) in self.classes.iter().enumerate() {
            yaml.push_str(&format!("  {k}: {c}\n"));
        }
        let p = self.dir.join("data.yaml");
        write_atomic(&p, yaml.as_bytes()).map_err(io(&p))?;
        Ok(n_anns)
    }
}

/// YOLO lines `class cx cy w h` (normalised) for every detectable fish
/// (visible pixels and enough contrast), box of the visible silhouette.
pub fn yolo_labels(frame: &Frame) -> String {
    let (w, h) = (frame.width as f64, frame.height as f64);
    let mut s = String::new();
    for f in frame.fish.iter().filter(|f| f.detectable) {
        if let Some([x0, y0, x1, y1]) = f.box_visible {
            let (x0, y0, x1, y1) = (x0 as f64, y0 as f64, x1 as f64, y1 as f64);
            s.push_str(&format!(
                "{} {:.6} {:.6} {:.6} {:.6}\n",
                f.species,
                (x0 + x1) / 2.0 / w,
                (y0 + y1) / 2.0 / h,
                (x1 - x0) / w,
                (y1 - y0) / h
            ));
        }
    }
    s
}

/// The instance mask as a 16-bit grayscale PNG.
pub fn encode_mask(frame: &Frame) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::with_capacity(frame.ids.len() * 2);
    for v in &frame.ids {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    let mut buf = Vec::new();
    image::ImageEncoder::write_image(
        image::codecs::png::PngEncoder::new_with_quality(
            Cursor::new(&mut buf),
            image::codecs::png::CompressionType::Fast,
            image::codecs::png::FilterType::Sub,
        ),
        &bytes_to_native(&bytes),
        frame.width,
        frame.height,
        image::ExtendedColorType::L16,
    )
    .map_err(|e| e.to_string())?;
    Ok(buf)
}

/// `write_image` takes L16 samples in native byte order.
fn bytes_to_native(be: &[u8]) -> Vec<u8> {
    be.chunks_exact(2)
        .flat_map(|c| u16::from_be_bytes([c[0], c[1]]).to_ne_bytes())
        .collect()
}

/// COCO run-length counts of the pixels with id `id` (column-major, starting
/// with a run of zeros), looking only inside `bx`.
pub fn rle_counts(frame: &Frame, id: u16, bx: [u32; 4]) -> Vec<u32> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    // Foreground pixels in column-major order are increasing indices.
    let mut on = Vec::new();
    for x in bx[0] as usize..bx[2] as usize {
        for y in bx[1] as usize..bx[3] as usize {
            if frame.ids[y * w + x] == id {
                on.push(x * h + y);
            }
        }
    }
    let (mut counts, mut pos, mut i) = (Vec::new(), 0usize, 0usize);
    while i < on.len() {
        let start = on[i];
        let mut end = start + 1;
        i += 1;
        while i < on.len() && on[i] == end {
            end += 1;
            i += 1;
        }
        counts.push((start - pos) as u32);
        counts.push((end - start) as u32);
        pos = end;
    }
    counts.push((w * h - pos) as u32);
    counts
}

/// pycocotools' compressed RLE string (`rleToString` of `maskApi.c`).
pub fn rle_string(counts: &[u32]) -> String {
    let mut s = String::new();
    for i in 0..counts.len() {
        let mut x = counts[i] as i64;
        if i > 2 {
            x -= counts[i - 2] as i64;
        }
        loop {
            let mut c = (x & 0x1f) as u8;
            x >>= 5;
            let more = if c & 0x10 != 0 { x != -1 } else { x != 0 };
            if more {
                c |= 0x20;
            }
            s.push((c + 48) as char);
            if !more {
                break;
            }
        }
    }
    s
}

/// Inverse of [`rle_string`] (`rleFrString`), for tests.
pub fn rle_from_string(s: &str) -> Vec<u32> {
    let b = s.as_bytes();
    let (mut p, mut counts) = (0usize, Vec::<i64>::new());
    while p < b.len() {
        let (mut x, mut k, mut more) = (0i64, 0, true);
        while more {
            let c = (b[p] - 48) as i64;
            x |= (c & 0x1f) << (5 * k);
            more = c & 0x20 != 0;
            p += 1;
            k += 1;
            if !more && c & 0x10 != 0 {
                x |= -1i64 << (5 * k);
            }
        }
        let m = counts.len();
        if m > 2 {
            x += counts[m - 2];
        }
        counts.push(x);
    }
    counts.into_iter().map(|c| c as u32).collect()
}
