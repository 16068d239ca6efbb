//! 8-bit grayscale JPEG, both ways: how a recording stores a frame compactly
//! (`deckwatch_flight`) and how the simulator gives a frame a stream's compression
//! (`deckwatch_sim::render::isp`). Behind the `jpeg` feature.

/// Why a grayscale JPEG could not be written or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("jpeg: {0}")]
pub struct JpegError(pub String);

/// `packed` (rows of `width` bytes, no padding) as a grayscale JPEG of `quality` (1-100).
pub fn encode_gray(packed: &[u8], width: usize, height: usize, quality: u8) -> Result<Vec<u8>, JpegError> {
    let (w, h) = (
        u16::try_from(width).map_err(|_| JpegError(format!("width {width} exceeds 65535")))?,
        u16::try_from(height).map_err(|_| JpegError(format!("height {height} exceeds 65535")))?,
    );
    let mut out = Vec::with_capacity(packed.len() / 8);
    jpeg_encoder::Encoder::new(&mut out, quality)
        .encode(packed, w, h, jpeg_encoder::ColorType::Luma)
        .map_err(|e| JpegError(e.to_string()))?;
    Ok(out)
}

/// A grayscale JPEG's width, height and packed rows; any other pixel format is refused.
/// The header's size is checked (`camera::check_image_size`) before anything is decoded, and
/// the decoder's own buffer limit set to it.
pub fn decode_gray(data: &[u8]) -> Result<(u32, u32, Vec<u8>), JpegError> {
    let mut decoder = jpeg_decoder::Decoder::new(data);
    decoder.read_info().map_err(|e| JpegError(e.to_string()))?;
    let header = decoder.info().ok_or_else(|| JpegError("no header".into()))?;
    crate::camera::check_image_size(u32::from(header.width), u32::from(header.height)).map_err(JpegError)?;
    decoder.set_max_decoding_buffer_size(crate::camera::MAX_IMAGE_PIXELS as usize);
    let pixels = decoder.decode().map_err(|e| JpegError(e.to_string()))?;
    let info = decoder.info().ok_or_else(|| JpegError("no header".into()))?;
    if info.pixel_format != jpeg_decoder::PixelFormat::L8 {
        return Err(JpegError(format!(
            "{:?} (deckwatch reads 8-bit grayscale)",
            info.pixel_format
        )));
    }
    Ok((u32::from(info.width), u32::from(info.height), pixels))
}

/// A photograph's width, height and grey rows: an 8-bit grey JPEG as it is, an RGB one by
/// [`crate::image::luma_bt601`], a 16-bit grey one by its high bytes; the size checked as in
/// [`decode_gray`].
pub fn decode_to_gray(data: &[u8]) -> Result<(u32, u32, Vec<u8>), JpegError> {
    let mut decoder = jpeg_decoder::Decoder::new(data);
    decoder.read_info().map_err(|e| JpegError(e.to_string()))?;
    let header = decoder.info().ok_or_else(|| JpegError("no header".into()))?;
    crate::camera::check_image_size(u32::from(header.width), u32::from(header.height)).map_err(JpegError)?;
    decoder.set_max_decoding_buffer_size(3 * crate::camera::MAX_IMAGE_PIXELS as usize);
    let pixels = decoder.decode().map_err(|e| JpegError(e.to_string()))?;
    let info = decoder.info().ok_or_else(|| JpegError("no header".into()))?;
    let grey = match info.pixel_format {
        jpeg_decoder::PixelFormat::L8 => pixels,
        jpeg_decoder::PixelFormat::RGB24 => pixels
            .chunks_exact(3)
            .map(|p| crate::image::luma_bt601(p[0], p[1], p[2]))
            .collect(),
        // Big-endian: the high byte first.
        jpeg_decoder::PixelFormat::L16 => pixels.chunks_exact(2).map(|p| p[0]).collect(),
        f => return Err(JpegError(format!("{f:?} (deckwatch reads grey and RGB)"))),
    };
    Ok((u32::from(info.width), u32::from(info.height), grey))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A colour photograph becomes its luma; a grey one stays as it is; a recording's decoder
    /// still refuses the colour one.
    #[test]
    fn a_colour_jpeg_becomes_its_luma() {
        let red: Vec<u8> = [200u8, 30, 60].repeat(16 * 16);
        let mut rgb = Vec::new();
        jpeg_encoder::Encoder::new(&mut rgb, 100)
            .encode(&red, 16, 16, jpeg_encoder::ColorType::Rgb)
            .unwrap();
        let (w, h, grey) = decode_to_gray(&rgb).unwrap();
        let expected = crate::image::luma_bt601(200, 30, 60);
        assert_eq!((w, h, grey.len()), (16, 16, 256));
        assert!(
            grey.iter().all(|v| v.abs_diff(expected) <= 3),
            "{grey:?} vs {expected}"
        );
        assert!(decode_gray(&rgb).is_err());
        let flat = encode_gray(&[90; 64], 8, 8, 100).unwrap();
        assert!(decode_to_gray(&flat)
            .unwrap()
            .2
            .iter()
            .all(|v| v.abs_diff(90) <= 1));
    }

    #[test]
    fn a_gray_frame_goes_there_and_back() {
        let packed: Vec<u8> = (0..64 * 48).map(|i| (i % 64 * 4) as u8).collect();
        let (w, h, back) = decode_gray(&encode_gray(&packed, 64, 48, 95).unwrap()).unwrap();
        assert_eq!((w, h, back.len()), (64, 48, packed.len()));
        assert!(packed.iter().zip(&back).all(|(a, b)| a.abs_diff(*b) <= 8));
        assert!(encode_gray(&packed, 70_000, 1, 90).is_err());
        assert!(decode_gray(b"not a jpeg").is_err());
    }

    /// A small file whose header claims 30 000 x 30 000 (900 MP, 900 MB of pixels) is refused
    /// from its header, before any pixel is decoded.
    #[test]
    fn a_huge_header_is_refused_before_decoding() {
        let packed = vec![128u8; 16 * 16];
        let mut jpeg = encode_gray(&packed, 16, 16, 90).unwrap();
        // SOF0: FF C0, length (2), precision (1), height (2), width (2).
        let sof = jpeg.windows(2).position(|w| w == [0xff, 0xc0]).unwrap();
        jpeg[sof + 5..sof + 9].copy_from_slice(&[0x75, 0x30, 0x75, 0x30]);
        let e = decode_gray(&jpeg).unwrap_err();
        assert!(e.0.contains("30000x30000"), "{e}");
    }
}
