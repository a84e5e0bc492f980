//! Splitting a frame into tiles for farm tasks: tile `i` of `n` is a fixed rectangle of
//! the full image, the same on every machine. Pixel streams are seeded from the global
//! pixel index, so a tile renders exactly the pixels a one-machine render gives it.

use crate::render::film::Region;

/// Tile `index` of `count` (0-based) of a `width` × `height` frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tile {
    pub index: u32,
    pub count: u32,
}

impl Tile {
    /// Parses `I/N` (0 ≤ I < N).
    pub fn parse(s: &str) -> Result<Tile, String> {
        let bad = || format!("tile '{s}' is not of the form I/N with 0 <= I < N, e.g. 3/16");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Tile { index, count })
    }

    /// The grid of `count` tiles: as square as the count allows with every tile of one
    /// row (`cols` × `rows` = `count`; a prime count gives horizontal bands).
    pub fn grid(count: u32) -> (u32, u32) {
        let mut cols = (count as f64).sqrt().floor() as u32;
        while cols > 1 && count % cols != 0 {
            cols -= 1;
        }
        let cols = cols.max(1);
        (cols, count / cols)
    }

    /// The pixels of this tile in a `width` × `height` frame, or an error when the
    /// frame has fewer pixels than the grid needs in a direction.
    pub fn region(&self, width: u32, height: u32) -> Result<Region, String> {
        let (cols, rows) = Tile::grid(self.count);
        if cols > width || rows > height {
            return Err(format!(
                "{} tiles ({cols} x {rows}) do not fit a {width}x{height} frame",
                self.count
            ));
        }
        let (cx, cy) = (self.index % cols, self.index / cols);
        // Even splits: edge k at floor(k·size / parts), so tiles differ by at most one
        // pixel and cover the frame exactly.
        let edge = |k: u32, size: u32, parts: u32| (k as u64 * size as u64 / parts as u64) as u32;
        Ok(Region {
            x0: edge(cx, width, cols),
            x1: edge(cx + 1, width, cols),
            y0: edge(cy, height, rows),
            y1: edge(cy + 1, height, rows),
        })
    }

    /// `name` with `.tileII` (zero-padded to the width of `count − 1`) before the
    /// extension: `out.exr` → `out.tile03.exr`.
    pub fn file_name(&self, name: &str) -> String {
        let width = (self.count - 1).max(1).to_string().len();
        let tag = format!("tile{:0width$}", self.index);
        match name.rfind('.').filter(|&i| i > 0) {
            Some(dot) => format!("{}.{tag}{}", &name[..dot], &name[dot..]),
            None => format!("{name}.{tag}"),
        }
    }
}

/// Parses an explicit region `x0,y0,x1,y1` (pixels `x0..x1` × `y0..y1`).
pub fn parse_region(s: &str) -> Result<Region, String> {
    let bad = || format!("region '{s}' is not of the form X0,Y0,X1,Y1 with X0 < X1, Y0 < Y1");
    let v: Vec<u32> = s
        .split(',')
        .map(|p| p.trim().parse::<u32>())
        .collect::<Result<_, _>>()
        .map_err(|_| bad())?;
    let [x0, y0, x1, y1] = v[..] else {
        return Err(bad());
    };
    if x0 >= x1 || y0 >= y1 {
        return Err(bad());
    }
    Ok(Region { x0, y0, x1, y1 })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tiles of every count up to 40 cover a frame exactly once.
    #[test]
    fn tiles_partition_the_frame() {
        for count in 1..=40 {
            for (w, h) in [(320, 240), (37, 23), (41, 41)] {
                let mut hits = vec![0u8; (w * h) as usize];
                for index in 0..count {
                    let Ok(r) = (Tile { index, count }).region(w, h) else {
                        continue;
                    };
                    for y in r.y0..r.y1 {
                        for x in r.x0..r.x1 {
                            hits[(y * w + x) as usize] += 1;
                        }
                    }
                }
                if Tile::grid(count).0 <= w && Tile::grid(count).1 <= h {
                    assert!(hits.iter().all(|&n| n == 1), "{count} tiles of {w}x{h}");
                }
            }
        }
    }

    #[test]
    fn grids_are_square_where_the_count_allows() {
        assert_eq!(Tile::grid(16), (4, 4));
        assert_eq!(Tile::grid(4), (2, 2));
        assert_eq!(Tile::grid(6), (2, 3));
        assert_eq!(Tile::grid(7), (1, 7));
        assert_eq!(Tile::grid(1), (1, 1));
    }

    #[test]
    fn parsing_and_names() {
        assert_eq!(
            Tile::parse("3/16"),
            Ok(Tile {
                index: 3,
                count: 16
            })
        );
        assert!(Tile::parse("16/16").is_err());
        assert!(Tile::parse("0/0").is_err());
        assert!(Tile::parse("a/4").is_err());
        assert_eq!(
            Tile {
                index: 3,
                count: 16
            }
            .file_name("out.exr"),
            "out.tile03.exr"
        );
        assert_eq!(
            Tile { index: 3, count: 4 }.file_name("shot.0001.exr"),
            "shot.0001.tile3.exr"
        );
        assert_eq!(
            parse_region("1,2,30,40"),
            Ok(Region {
                x0: 1,
                y0: 2,
                x1: 30,
                y1: 40
            })
        );
        assert!(parse_region("3,2,3,40").is_err());
    }
}
