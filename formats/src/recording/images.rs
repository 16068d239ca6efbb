//! The recording's images: 8-bit grayscale PNG, decoded into the caller's buffer and checked
//! against the recording's size.

use super::*;

/// Decodes an 8-bit grayscale PNG into `out` (tightly packed). With `expect`, the image must have
/// that size. Any other PNG kind is an error: recordings are 8-bit grayscale by definition.
pub fn decode_gray_png(
    path: &Path,
    expect: Option<(usize, usize)>,
    out: &mut [u8],
) -> Result<(usize, usize), RecordingError> {
    let file = File::open(path).map_err(|e| RecordingError::new(path, format!("cannot read image: {e}")))?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder
        .read_info()
        .map_err(|e| RecordingError::new(path, format!("not a readable PNG: {e}")))?;
    let info = reader.info();
    let (w, h) = (info.width as usize, info.height as usize);
    if info.color_type != png::ColorType::Grayscale || info.bit_depth != png::BitDepth::Eight {
        return Err(RecordingError::new(
            path,
            format!(
                "PNG is {:?} {:?}; recordings hold 8-bit grayscale",
                info.bit_depth, info.color_type
            ),
        ));
    }
    if let Some((ew, eh)) = expect {
        if (w, h) != (ew, eh) {
            return Err(RecordingError::new(
                path,
                format!("image is {w}x{h}, camera.json says {ew}x{eh}"),
            ));
        }
    }
    if out.len() < w * h {
        return Err(RecordingError::new(
            path,
            format!("output buffer has {} bytes, the image needs {}", out.len(), w * h),
        ));
    }
    reader
        .next_frame(&mut out[..w * h])
        .map_err(|e| RecordingError::new(path, format!("corrupt PNG data: {e}")))?;
    Ok((w, h))
}

/// Encodes an 8-bit grayscale image as PNG (fast compression: recordings are written live).
pub fn encode_gray_png(path: &Path, image: GrayView<'_>) -> Result<(), RecordingError> {
    let err = |e: &dyn fmt::Display| RecordingError::new(path, format!("cannot write image: {e}"));
    let file = File::create(path).map_err(|e| err(&e))?;
    let mut enc = png::Encoder::new(BufWriter::new(file), image.width() as u32, image.height() as u32);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_compression(png::Compression::Fast);
    let mut writer = enc.write_header().map_err(|e| err(&e))?;
    {
        // Row by row, so a strided view (e.g. shared memory) needs no packed copy.
        let mut stream = writer.stream_writer().map_err(|e| err(&e))?;
        for y in 0..image.height() {
            stream.write_all(image.row(y)).map_err(|e| err(&e))?;
        }
        stream.finish().map_err(|e| err(&e))?;
    }
    writer.finish().map_err(|e| err(&e))
}
