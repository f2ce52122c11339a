//! Images out of a Stokes image (docs/render.md, "Outputs"): tone-mapped
//! intensity, degree of polarization in the Wilkie–Weidlich style, false
//! colour `S1/S2/S3`, raw Stokes `.npy`; and PNG decoding for environment
//! maps. Byte buffers in, byte buffers out: files are the caller's.

use super::integrator::StokesImage;
use super::material::MAX_CHANNELS;
use super::polarization::Stokes;
use crate::brdf::export::{NpyType, npy_bytes};
use crate::physics::stokes::degree_of_polarization;

/// Rec. 709 luminance weights of (R, G, B).
pub const LUMINANCE_RGB: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Weights that fold the channels into one "visual" Stokes vector: 1 for a
/// one-channel image; for three channels (ascending wavelength, shown as
/// B, G, R) the luminance weights of B, G, R.
pub fn channel_weights(channels: usize) -> [f64; MAX_CHANNELS] {
    if channels == 3 {
        [LUMINANCE_RGB[2], LUMINANCE_RGB[1], LUMINANCE_RGB[0]]
    } else {
        [1.0, 0.0, 0.0]
    }
}

/// The luminance-weighted Stokes vector of a pixel (see [`channel_weights`]).
pub fn visual_stokes(img: &StokesImage, x: usize, y: usize) -> Stokes {
    let w = channel_weights(img.channels);
    let mut s = [0.0; 4];
    for (c, wc) in w.iter().enumerate().take(img.channels) {
        let v = img.stokes(x, y, c);
        for k in 0..4 {
            s[k] += wc * v[k];
        }
    }
    s
}

/// sRGB transfer function (IEC 61966-2-1) of a linear value in `[0, 1]`.
pub fn srgb_encode(v: f64) -> f64 {
    let v = v.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// sRGB decoding of a value in `[0, 1]` to linear.
pub fn srgb_decode(v: f64) -> f64 {
    if v <= 0.040_45 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn byte(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Automatic exposure: the value that maps the 99th percentile of the
/// luminance of lit pixels to 0.9 (so highlights clip, the rest is kept);
/// 1 for a black image.
pub fn auto_exposure(img: &StokesImage) -> f64 {
    let mut lum: Vec<f64> = (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .map(|(x, y)| visual_stokes(img, x, y)[0])
        .filter(|&v| v > 0.0)
        .collect();
    if lum.is_empty() {
        return 1.0;
    }
    lum.sort_by(f64::total_cmp);
    let p = lum[((lum.len() - 1) as f64 * 0.99).round() as usize];
    if p > 0.0 { 0.9 / p } else { 1.0 }
}

/// Tone-mapped intensity, RGB8 row-major: `sRGB(clamp(exposure · I))` per
/// channel; a one-channel image is grey, three channels are shown as
/// B, G, R in ascending wavelength.
pub fn intensity_rgb8(img: &StokesImage, exposure: f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(img.width * img.height * 3);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = |c: usize| byte(srgb_encode(exposure * img.stokes(x, y, c)[0]));
            if img.channels == 3 {
                out.extend_from_slice(&[v(2), v(1), v(0)]);
            } else {
                let g = v(0);
                out.extend_from_slice(&[g, g, g]);
            }
        }
    }
    out
}

/// Degree of polarization (seed eq. 1) of the visual Stokes vector, as in
/// Wilkie & Weidlich (2010) (seed ref. 17): black for unpolarized, pure red
/// rising linearly in display value to full red at `DOP = dop_max`; pixels
/// without light are black.
pub fn dop_rgb8(img: &StokesImage, dop_max: f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(img.width * img.height * 3);
    for y in 0..img.height {
        for x in 0..img.width {
            let p = degree_of_polarization(visual_stokes(img, x, y));
            out.extend_from_slice(&[byte(p / dop_max), 0, 0]);
        }
    }
    out
}

/// False colour of one normalised Stokes component `S_k / I` (`k = 1, 2, 3`)
/// of the visual Stokes vector, after Wilkie & Weidlich (2010): for the
/// linear components `S1`, `S2` positive values green, negative red; for the
/// circular `S3` positive yellow, negative blue; black at 0 and full colour
/// at `|S_k/I| = scale`.
pub fn component_rgb8(img: &StokesImage, k: usize, scale: f64) -> Vec<u8> {
    let mut out = Vec::with_capacity(img.width * img.height * 3);
    for y in 0..img.height {
        for x in 0..img.width {
            let s = visual_stokes(img, x, y);
            let v = if s[0] > 0.0 { s[k] / s[0] / scale } else { 0.0 };
            let a = byte(v.abs());
            let px = match (k == 3, v >= 0.0) {
                (false, true) => [0, a, 0],
                (false, false) => [a, 0, 0],
                (true, true) => [a, a, 0],
                (true, false) => [0, 0, a],
            };
            out.extend_from_slice(&px);
        }
    }
    out
}

/// PNG (RGB, 8 bit) of a row-major RGB8 buffer.
pub fn png_rgb8(width: usize, height: usize, rgb: &[u8]) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    {
        let w = u32::try_from(width).map_err(|e| e.to_string())?;
        let h = u32::try_from(height).map_err(|e| e.to_string())?;
        let mut enc = png::Encoder::new(&mut bytes, w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = enc.write_header().map_err(|e| e.to_string())?;
        writer.write_image_data(rgb).map_err(|e| e.to_string())?;
        writer.finish().map_err(|e| e.to_string())?;
    }
    Ok(bytes)
}

/// The raw Stokes image as `.npy` float32: shape `(H, W, 4)` for one
/// channel, `(H, W, C, 4)` for `C` channels (ascending wavelength); in the
/// camera's Stokes frame, after the polarizer.
pub fn stokes_npy(img: &StokesImage) -> Result<Vec<u8>, String> {
    let shape: Vec<usize> = if img.channels == 1 {
        vec![img.height, img.width, 4]
    } else {
        vec![img.height, img.width, img.channels, 4]
    };
    npy_bytes(&shape, &img.data, NpyType::F32).map_err(|e| e.to_string())
}

/// A decoded image: linear RGB texels, row-major.
#[derive(Clone, Debug)]
pub struct LinearImage {
    /// Width.
    pub width: usize,
    /// Height.
    pub height: usize,
    /// Linear (R, G, B) per texel.
    pub rgb: Vec<[f64; 3]>,
}

/// Decode a PNG (grey, grey+alpha, RGB, RGBA, indexed; 8 or 16 bit) to
/// linear RGB with the sRGB transfer function; alpha is ignored.
pub fn decode_png(bytes: &[u8]) -> Result<LinearImage, String> {
    let mut dec = png::Decoder::new(std::io::Cursor::new(bytes));
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(|e| format!("PNG: {e}"))?;
    let mut buf = vec![0; reader.output_buffer_size().ok_or("PNG: image too large")?];
    let info = reader
        .next_frame(&mut buf)
        .map_err(|e| format!("PNG: {e}"))?;
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.color_type.samples();
    let sixteen = info.bit_depth == png::BitDepth::Sixteen;
    let sample = |i: usize| -> f64 {
        if sixteen {
            u16::from_be_bytes([buf[2 * i], buf[2 * i + 1]]) as f64 / 65535.0
        } else {
            buf[i] as f64 / 255.0
        }
    };
    let mut rgb = Vec::with_capacity(w * h);
    for p in 0..w * h {
        let b = p * channels;
        let px = match channels {
            1 | 2 => {
                let g = srgb_decode(sample(b));
                [g, g, g]
            }
            _ => [
                srgb_decode(sample(b)),
                srgb_decode(sample(b + 1)),
                srgb_decode(sample(b + 2)),
            ],
        };
        rgb.push(px);
    }
    Ok(LinearImage {
        width: w,
        height: h,
        rgb,
    })
}

/// Decode a `.npy` float image (`<f4`/`<f8`, C order, shape `(H, W)` or
/// `(H, W, 3)`), taken as linear radiance.
pub fn decode_npy(bytes: &[u8]) -> Result<LinearImage, String> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err("npy: not a .npy file".into());
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err("npy: truncated header".into());
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(format!("npy: unsupported version {v}")),
    };
    let header = std::str::from_utf8(
        bytes
            .get(start..start + hlen)
            .ok_or("npy: truncated header")?,
    )
    .map_err(|_| "npy: header is not text")?;
    let size = if header.contains("'<f4'") {
        4
    } else if header.contains("'<f8'") {
        8
    } else {
        return Err(format!("npy: need '<f4' or '<f8' data, header {header}"));
    };
    if header.contains("'fortran_order': True") {
        return Err("npy: Fortran order is not supported".into());
    }
    let shape_txt = header
        .split("'shape':")
        .nth(1)
        .and_then(|s| s.split('(').nth(1))
        .and_then(|s| s.split(')').next())
        .ok_or("npy: no shape in the header")?;
    let shape: Vec<usize> = shape_txt
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse()
                .map_err(|_| format!("npy: bad shape ({shape_txt})"))
        })
        .collect::<Result<_, _>>()?;
    let (h, w, c) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, 3] => (*h, *w, 3),
        _ => {
            return Err(format!(
                "npy: need shape (H, W) or (H, W, 3), got {shape:?}"
            ));
        }
    };
    let data = &bytes[start + hlen..];
    if data.len() != h * w * c * size || h == 0 || w == 0 {
        return Err("npy: data size does not match the shape".into());
    }
    let value = |i: usize| -> f64 {
        let b = &data[i * size..(i + 1) * size];
        if size == 4 {
            f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64
        } else {
            f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]])
        }
    };
    let mut rgb = Vec::with_capacity(w * h);
    for p in 0..w * h {
        let px = if c == 1 {
            let v = value(p);
            [v, v, v]
        } else {
            [value(3 * p), value(3 * p + 1), value(3 * p + 2)]
        };
        if px.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(format!("npy: texel {p} is negative or not finite"));
        }
        rgb.push(px);
    }
    Ok(LinearImage {
        width: w,
        height: h,
        rgb,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(values: &[Stokes]) -> StokesImage {
        StokesImage {
            width: values.len(),
            height: 1,
            channels: 1,
            data: values.iter().flatten().copied().collect(),
            objects: vec![None; values.len()],
        }
    }

    #[test]
    fn srgb_round_trips() {
        for v in [0.0, 0.002, 0.01, 0.2, 0.5, 1.0] {
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-12);
        }
        assert_eq!(byte(srgb_encode(1.0)), 255);
    }

    /// DOP image: black at DOP 0 and where there is no light, full red at
    /// `dop_max`, linear in between.
    #[test]
    fn dop_is_black_to_red() {
        let img = image(&[
            [1.0, 0.0, 0.0, 0.0],
            [2.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 1.0],
            [0.0; 4],
        ]);
        let px = dop_rgb8(&img, 1.0);
        assert_eq!(&px[0..3], &[0, 0, 0]);
        assert_eq!(&px[3..6], &[128, 0, 0]);
        assert_eq!(&px[6..9], &[255, 0, 0]);
        assert_eq!(&px[9..12], &[0, 0, 0]);
        assert_eq!(&dop_rgb8(&img, 0.5)[3..6], &[255, 0, 0]);
        let s1 = component_rgb8(
            &image(&[[1.0, -0.5, 0.0, 0.0], [1.0, 1.0, 0.0, 0.0]]),
            1,
            1.0,
        );
        assert_eq!(s1, vec![128, 0, 0, 0, 255, 0]);
        let s3 = component_rgb8(
            &image(&[[1.0, 0.0, 0.0, -1.0], [1.0, 0.0, 0.0, 1.0]]),
            3,
            1.0,
        );
        assert_eq!(s3, vec![0, 0, 255, 255, 255, 0]);
    }

    /// PNG and npy round trips through our own decoders.
    #[test]
    fn png_and_npy_round_trip() {
        let rgb: Vec<u8> = (0..4 * 3 * 3).map(|k| (k * 7) as u8).collect();
        let png = png_rgb8(4, 3, &rgb).unwrap();
        let back = decode_png(&png).unwrap();
        assert_eq!((back.width, back.height), (4, 3));
        for (p, px) in back.rgb.iter().enumerate() {
            for c in 0..3 {
                let v = srgb_encode(px[c]);
                assert!((v * 255.0 - rgb[3 * p + c] as f64).abs() < 1e-9);
            }
        }
        let img = StokesImage {
            width: 2,
            height: 3,
            channels: 3,
            data: (0..2 * 3 * 3 * 4).map(|k| k as f64).collect(),
            objects: vec![None; 6],
        };
        let npy = stokes_npy(&img).unwrap();
        let header = String::from_utf8_lossy(&npy[10..npy.len() - 4 * img.data.len()]).into_owned();
        assert!(header.contains("'shape': (3, 2, 3, 4)"), "{header}");
        let env = npy_bytes(
            &[2, 3, 3],
            &(0..18).map(|k| k as f64).collect::<Vec<_>>(),
            NpyType::F64,
        )
        .unwrap();
        let e = decode_npy(&env).unwrap();
        assert_eq!((e.width, e.height), (3, 2));
        assert_eq!(e.rgb[4], [12.0, 13.0, 14.0]);
        assert!(decode_npy(b"nonsense").is_err());
    }
}
