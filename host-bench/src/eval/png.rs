//! Every plot as PNG too: the SVG plotters drew, rendered by resvg with the font bundled in
//! `assets/fonts` (DejaVu Sans), so the picture is the same on every machine, with or without
//! fonts installed, and no C library (freetype, fontconfig) is built.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use anyhow::{Context as _, Result};
use resvg::{tiny_skia, usvg};

use crate::formats::atomic::Staged;

const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

fn options() -> &'static usvg::Options<'static> {
    static OPTIONS: OnceLock<usvg::Options<'static>> = OnceLock::new();
    OPTIONS.get_or_init(|| {
        let mut db = usvg::fontdb::Database::new();
        db.load_font_data(FONT.to_vec());
        // plotters names `sans-serif` (and sometimes a family of its own): all map to the one
        // font there is.
        db.set_sans_serif_family("DejaVu Sans");
        db.set_serif_family("DejaVu Sans");
        db.set_monospace_family("DejaVu Sans");
        let mut opts = usvg::Options {
            font_family: "DejaVu Sans".into(),
            ..Default::default()
        };
        opts.fontdb = Arc::new(db);
        opts
    })
}

/// The PNG of `svg`, at the SVG's own size in pixels.
pub fn render(svg: &str) -> Result<Vec<u8>> {
    let tree = usvg::Tree::from_str(svg, options()).context("the plot's SVG does not parse")?;
    let size = tree.size().to_int_size();
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .context("the plot has no area to render")?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(&tree, tiny_skia::Transform::default(), &mut pixmap.as_mut());
    pixmap.encode_png().context("encoding the plot as PNG")
}

/// Stages `svg` at `svg_path` and its PNG beside it ([`beside`]): both files or neither.
pub fn stage(staged: &mut Staged, svg_path: &Path, svg: &str) -> Result<()> {
    let png = render(svg).with_context(|| format!("the PNG of {}", svg_path.display()))?;
    staged.write(svg_path, |f| Ok(f.write_all(svg.as_bytes())?))?;
    staged.write(&beside(svg_path), |f| Ok(f.write_all(&png)?))
}

/// Writes `svg` to `svg_path` and its PNG beside it, both or neither.
pub fn write(svg_path: &Path, svg: &str) -> Result<()> {
    let mut staged = Staged::default();
    stage(&mut staged, svg_path, svg)?;
    staged.commit()
}

/// `x.svg` → `x.png`.
pub fn beside(svg_path: &Path) -> PathBuf {
    svg_path.with_extension("png")
}

#[cfg(test)]
mod tests {
    #[test]
    fn text_is_drawn_with_the_bundled_font() {
        let blank = r#"<svg xmlns="http://www.w3.org/2000/svg" width="120" height="40"></svg>"#;
        let text = r#"<svg xmlns="http://www.w3.org/2000/svg" width="120" height="40"><text x="5" y="25" font-family="sans-serif" font-size="20">error mm</text></svg>"#;
        let (a, b) = (super::render(blank).unwrap(), super::render(text).unwrap());
        assert_eq!(&b[1..4], b"PNG");
        // The same size, and the text's pixels make the second compress worse.
        assert!(b.len() > a.len() + 100, "{} vs {} bytes", b.len(), a.len());
    }
}
