//! Input frames: a folder of PNG/JPEG files (sorted by name), or a video
//! decoded by the system's `ffmpeg` into raw RGB frames on a pipe (no codec
//! is compiled into deepfoids; `ffprobe` reads the frame size first).

use crate::error::{CountError, Result};
use image::RgbImage;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// Image files of a folder, sorted by name.
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(CountError::io(dir))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg"))
        })
        .collect();
    v.sort();
    if v.is_empty() {
        return Err(CountError::NoFrames {
            path: dir.to_path_buf(),
        });
    }
    Ok(v)
}

/// Read an image as RGB.
pub fn read_image(path: &Path) -> Result<RgbImage> {
    image::open(path)
        .map(|i| i.to_rgb8())
        .map_err(|e| CountError::Image {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
}

/// Frames one after another: `(name, image)`.
pub enum Frames {
    Folder {
        files: Vec<PathBuf>,
        next: usize,
    },
    Video {
        path: PathBuf,
        child: Child,
        width: u32,
        height: u32,
        index: usize,
    },
}

impl Frames {
    /// Open a folder of frames or a video file.
    pub fn open(input: &Path) -> Result<Self> {
        if input.is_dir() {
            return Ok(Self::Folder {
                files: list_images(input)?,
                next: 0,
            });
        }
        if !input.is_file() {
            return Err(CountError::Missing {
                path: input.to_path_buf(),
            });
        }
        let video_err = |message: String| CountError::Video {
            path: input.to_path_buf(),
            message,
        };
        let missing = |tool: &str, e: std::io::Error| {
            video_err(format!(
                "decoding a video needs the system's `{tool}` ({e}); install ffmpeg (e.g. `apt-get install ffmpeg`) or pass a folder of PNG/JPEG frames"
            ))
        };
        let probe = Command::new("ffprobe")
            .args([
                "-v",
                "error",
                "-select_streams",
                "v:0",
                "-show_entries",
                "stream=width,height",
                "-of",
                "csv=p=0:s=x",
            ])
            .arg(input)
            .output()
            .map_err(|e| missing("ffprobe", e))?;
        let text = String::from_utf8_lossy(&probe.stdout);
        let (width, height) = text
            .trim()
            .lines()
            .next()
            .and_then(|l| l.split_once('x'))
            .and_then(|(w, h)| Some((w.trim().parse().ok()?, h.trim().parse().ok()?)))
            .ok_or_else(|| {
                video_err(format!(
                    "not a video ffprobe can read: {}",
                    String::from_utf8_lossy(&probe.stderr).trim()
                ))
            })?;
        let child = Command::new("ffmpeg")
            .args(["-v", "error", "-nostdin", "-i"])
            .arg(input)
            .args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| missing("ffmpeg", e))?;
        Ok(Self::Video {
            path: input.to_path_buf(),
            child,
            width,
            height,
            index: 0,
        })
    }

    /// The next frame, or `None` at the end.
    pub fn next_frame(&mut self) -> Result<Option<(String, RgbImage)>> {
        match self {
            Self::Folder { files, next } => {
                let Some(p) = files.get(*next) else {
                    return Ok(None);
                };
                *next += 1;
                let name = p
                    .file_name()
                    .map_or_else(String::new, |n| n.to_string_lossy().into());
                Ok(Some((name, read_image(p)?)))
            }
            Self::Video {
                path,
                child,
                width,
                height,
                index,
            } => {
                let mut buf = vec![0u8; (*width * *height * 3) as usize];
                let out = child.stdout.as_mut().expect("piped");
                let mut got = 0;
                while got < buf.len() {
                    match out.read(&mut buf[got..]) {
                        Ok(0) => break,
                        Ok(n) => got += n,
                        Err(e) => {
                            return Err(CountError::Io {
                                path: path.clone(),
                                error: e,
                            });
                        }
                    }
                }
                if got < buf.len() {
                    let _ = child.wait();
                    return Ok(None);
                }
                let name = format!("{}#{}", path.display(), *index);
                *index += 1;
                Ok(Some((
                    name,
                    RgbImage::from_raw(*width, *height, buf).expect("size"),
                )))
            }
        }
    }
}

impl Drop for Frames {
    fn drop(&mut self) {
        if let Self::Video { child, .. } = self {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
