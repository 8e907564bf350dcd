//! Sliding windows (thesis §4.4.2, Eq. 4.7).
//!
//! A window of `SI × SI` (416) moves over the image by a step `s` of half the
//! window, horizontally and vertically. The thesis counts
//! `R = (⌊(I_w − SI_w)/s⌋ + 1) · (⌊(I_h − SI_h)/s⌋ + 1)` windows; they start at
//! multiples of `s`. When `I − SI` is not a multiple of `s` those windows miss
//! a strip at the far edge, so we add one window flush with it (its step to
//! the previous one is shorter than `s`). An image smaller than the window
//! gets one window at 0, padded.

/// One window: its top-left corner in the image (pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub x: u32,
    pub y: u32,
}

/// The thesis' window count `R` of Eq. 4.7 (an image smaller than the window counts 1 along that axis).
pub fn thesis_count(width: u32, height: u32, window: u32, step: u32) -> usize {
    let along = |len: u32| (len.saturating_sub(window) / step) as usize + 1;
    along(width) * along(height)
}

/// Window starts along one axis of length `len`: `0, s, 2s, …` while the
/// window fits, then one flush with the end if the last did not reach it.
pub fn starts(len: u32, window: u32, step: u32) -> Vec<u32> {
    if len <= window {
        return vec![0];
    }
    let mut v: Vec<u32> = (0..=(len - window) / step).map(|k| k * step).collect();
    if v.last().is_some_and(|&last| last + window < len) {
        v.push(len - window);
    }
    v
}

/// Every window over a `width × height` image, row by row.
pub fn windows(width: u32, height: u32, window: u32, step: u32) -> Vec<Window> {
    let xs = starts(width, window, step);
    starts(height, window, step)
        .into_iter()
        .flat_map(|y| xs.iter().map(move |&x| Window { x, y }))
        .collect()
}

/// The `window × window` crop at `w` of an RGB image (zero outside the image).
pub fn crop(img: &image::RgbImage, w: Window, window: u32) -> image::RgbImage {
    let mut out = image::RgbImage::new(window, window);
    let (iw, ih) = img.dimensions();
    let cw = window.min(iw.saturating_sub(w.x)) as usize;
    for row in 0..window.min(ih.saturating_sub(w.y)) {
        let src = ((w.y + row) * iw + w.x) as usize * 3;
        let dst = (row * window) as usize * 3;
        out.as_mut()[dst..dst + cw * 3].copy_from_slice(&img.as_raw()[src..src + cw * 3]);
    }
    out
}

/// The `window × window` crop at `w` of `[3, H, W]` planes of a
/// `width × height` image (zero outside the image), as `[3, window, window]`.
pub fn crop_planes(planes: &[f32], (iw, ih): (u32, u32), w: Window, window: u32) -> Vec<f32> {
    let (n, plane) = (window as usize, (iw * ih) as usize);
    let mut out = vec![0f32; 3 * n * n];
    let cw = window.min(iw.saturating_sub(w.x)) as usize;
    for c in 0..3 {
        for row in 0..window.min(ih.saturating_sub(w.y)) as usize {
            let src = c * plane + (w.y as usize + row) * iw as usize + w.x as usize;
            let dst = (c * n + row) * n;
            out[dst..dst + cw].copy_from_slice(&planes[src..src + cw]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 832 × 832 (the corrected fisheye view): starts 0, 208, 416 on each
    /// axis; Eq. 4.7: (⌊416/208⌋ + 1)² = 9, and no edge window is needed.
    #[test]
    fn square_view_is_the_thesis_count() {
        assert_eq!(starts(832, 416, 208), vec![0, 208, 416]);
        assert_eq!(thesis_count(832, 832, 416, 208), 9);
        assert_eq!(windows(832, 832, 416, 208).len(), 9);
    }

    /// 1280 × 720: Eq. 4.7 gives (⌊864/208⌋ + 1)·(⌊304/208⌋ + 1) = 5·2 = 10
    /// windows, which end at x = 832 + 416 = 1248 and y = 208 + 416 = 624; the
    /// flush windows at x = 864 and y = 304 cover the rest: 6·3 = 18.
    #[test]
    fn hd_frame_gets_flush_edge_windows() {
        assert_eq!(thesis_count(1280, 720, 416, 208), 10);
        assert_eq!(starts(1280, 416, 208), vec![0, 208, 416, 624, 832, 864]);
        assert_eq!(starts(720, 416, 208), vec![0, 208, 304]);
        let w = windows(1280, 720, 416, 208);
        assert_eq!(w.len(), 18);
        assert_eq!(w[5], Window { x: 864, y: 0 });
        assert_eq!(w[17], Window { x: 864, y: 304 });
        // Small images: one padded window.
        assert_eq!(thesis_count(300, 200, 416, 208), 1);
        assert_eq!(windows(300, 200, 416, 208), vec![Window { x: 0, y: 0 }]);
    }

    #[test]
    fn crop_copies_and_pads() {
        let img = image::RgbImage::from_fn(5, 4, |x, y| image::Rgb([x as u8, y as u8, 7]));
        let c = crop(&img, Window { x: 3, y: 1 }, 3);
        assert_eq!(c.get_pixel(0, 0).0, [3, 1, 7]);
        assert_eq!(c.get_pixel(1, 2).0, [4, 3, 7]);
        assert_eq!(c.get_pixel(2, 0).0, [0, 0, 0]); // x = 5: outside
        assert_eq!(c.get_pixel(0, 2).0, [3, 3, 7]);
    }

    /// The planes' crop is the pixels' crop, plane by plane, padding included.
    #[test]
    fn plane_crop_is_the_pixel_crop() {
        let img = image::RgbImage::from_fn(5, 4, |x, y| image::Rgb([x as u8, y as u8, 7]));
        let chw = crate::detector::to_chw(&img);
        for win in [
            Window { x: 3, y: 1 },
            Window { x: 0, y: 0 },
            Window { x: 4, y: 3 },
        ] {
            let want = crate::detector::to_chw(&crop(&img, win, 3));
            assert_eq!(crop_planes(&chw, (5, 4), win, 3), want, "{win:?}");
        }
    }
}
