//! The mixing report of the MCMC integrators (`mlt`, `pssmlt`, `mmlt`): per image block, the
//! rank-normalized split-R-hat and the bulk effective sample size (`math::mixing`, Vehtari et
//! al. 2021) of each chain's share of the image in that block, and a warning naming the blocks
//! whose chains have not mixed.
//!
//! Every step of a chain deposits a total luminance of one (in units of b: expected-value
//! splatting gives (1 - a) to the current path and a to the proposal); the statistic of chain c
//! in block k over a batch of steps is the fraction of its deposits that landed in k. Chains
//! that sample the same distribution agree on it (R-hat near 1, and the image there is the
//! average of chains that each saw the whole of it); chains that stay where they started
//! disagree, and the block's pixels are still converging. The batches of a chain double in
//! length whenever [`MAX_BATCHES`] are full (neighbours merged), so memory is bounded whatever
//! the chain's length, and long runs judge the chains over batches that are long too.
//!
//! The recorder only reads the deposits a step already made: it draws no random number and
//! changes no deposit, so the image is the same with or without it, whatever the threads.
//! Book: "Metropolis light transport", section "Have the chains mixed?".

use glam::Vec2;

use crate::math::mixing::{bulk_ess, rhat};
use crate::scene::Scene;
use crate::spectrum::{luminance, Rgb};

/// The side of a block in pixels (doubled until the grid has at most [`MAX_BLOCKS_PER_SIDE`]
/// blocks a side).
pub const BLOCK_SIZE: u32 = 8;
/// Blocks a side of the grid at most (the memory is chains x batches x blocks).
pub const MAX_BLOCKS_PER_SIDE: u32 = 16;
/// Batches a chain keeps at most; when full, neighbours are merged and the batch doubles.
pub const MAX_BATCHES: usize = 128;
/// A block has not mixed when its split-R-hat exceeds this. Vehtari et al. recommend 1.01 for
/// one quantity; the report judges up to 256 blocks at once from at most [`MAX_BATCHES`]
/// batches per chain, where the largest of 256 R-hats of well-mixed chains reaches 1.02 to 1.03,
/// so it warns at their more lenient 1.05.
pub const RHAT_THRESHOLD: f64 = 1.05;
/// ... or when its bulk ESS (in batches) is below this many per chain: the block's estimate then
/// rests on a few independent excursions of the chains.
pub const MIN_ESS_PER_CHAIN: f64 = 10.0;
/// Blocks named in the warning at most.
const NAMED_BLOCKS: usize = 4;

/// The image cut into square blocks of `size` pixels (the last row and column may be smaller).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockGrid {
    pub width: u32,
    pub height: u32,
    pub size: u32,
    pub cols: u32,
    pub rows: u32,
}

impl BlockGrid {
    /// The grid of a `width` x `height` image.
    pub fn new(width: u32, height: u32) -> Self {
        let mut size = BLOCK_SIZE;
        while width.div_ceil(size) > MAX_BLOCKS_PER_SIDE
            || height.div_ceil(size) > MAX_BLOCKS_PER_SIDE
        {
            size *= 2;
        }
        BlockGrid {
            width,
            height,
            size,
            cols: width.div_ceil(size),
            rows: height.div_ceil(size),
        }
    }

    /// The grid of the scene's camera (an empty grid without one).
    pub fn of(scene: &Scene) -> Self {
        scene
            .camera
            .as_ref()
            .map_or(Self::new(0, 0), |c| Self::new(c.width, c.height))
    }

    pub fn len(&self) -> usize {
        (self.cols * self.rows) as usize
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The block of film point `raster`, if it lies on the film.
    pub fn block(&self, raster: Vec2) -> Option<usize> {
        let (x, y) = (raster.x.floor(), raster.y.floor());
        if !(x >= 0.0 && y >= 0.0 && x < self.width as f32 && y < self.height as f32) {
            return None;
        }
        let (bx, by) = (x as u32 / self.size, y as u32 / self.size);
        Some((by * self.cols + bx) as usize)
    }

    /// Block `k`'s pixels, `x a-b, y c-d` (inclusive).
    pub fn name(&self, k: usize) -> String {
        let (bx, by) = (k as u32 % self.cols, k as u32 / self.cols);
        let x0 = bx * self.size;
        let y0 = by * self.size;
        let x1 = (x0 + self.size).min(self.width) - 1;
        let y1 = (y0 + self.size).min(self.height) - 1;
        format!("x {x0}-{x1}, y {y0}-{y1}")
    }
}

/// One chain's record: the means of its batches of steps, per block.
#[derive(Clone, Debug, Default)]
pub struct ChainTrace {
    /// Steps per finished batch (a power of two).
    batch_steps: u64,
    /// Steps in the batch under way.
    steps: u64,
    /// The batch under way: deposits per block.
    current: Vec<f64>,
    /// The finished batches' means, batch after batch, each `current.len()` values.
    batches: Vec<f32>,
}

impl ChainTrace {
    /// Records one step: its deposits (film point, value), in units of b.
    pub fn step(&mut self, grid: &BlockGrid, deposits: &[(Vec2, Rgb)]) {
        if self.current.len() != grid.len() {
            *self = ChainTrace {
                batch_steps: 1,
                current: vec![0.0; grid.len()],
                ..Default::default()
            };
        }
        for &(p, v) in deposits {
            let l = luminance(v) as f64;
            if let (Some(k), true) = (grid.block(p), l.is_finite()) {
                self.current[k] += l;
            }
        }
        self.steps += 1;
        if self.steps == self.batch_steps {
            let n = self.batch_steps as f64;
            self.batches
                .extend(self.current.iter().map(|s| (s / n) as f32));
            self.current.iter_mut().for_each(|s| *s = 0.0);
            self.steps = 0;
            if self.count() == MAX_BATCHES {
                self.batches = self.coarsened(2);
                self.batch_steps *= 2;
            }
        }
    }

    /// Finished batches.
    pub fn count(&self) -> usize {
        self.batches.len() / self.current.len().max(1)
    }

    /// The batches merged `factor` at a time (a trailing incomplete group left out).
    fn coarsened(&self, factor: usize) -> Vec<f32> {
        let blocks = self.current.len();
        let groups = self.count() / factor;
        let mut out = vec![0.0f32; groups * blocks];
        for (g, o) in out.chunks_mut(blocks).enumerate() {
            let group = &self.batches[g * factor * blocks..(g + 1) * factor * blocks];
            for b in group.chunks(blocks) {
                o.iter_mut()
                    .zip(b)
                    .for_each(|(o, v)| *o += v / factor as f32);
            }
        }
        out
    }

    /// Bytes a chain's record holds at most on `grid`.
    pub fn bytes(grid: &BlockGrid) -> u64 {
        (grid.len() * (MAX_BATCHES * 4 + 8)) as u64
    }
}

/// One block's diagnostics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockMixing {
    /// Rank-normalized split-R-hat (`None`: no chain deposited there, or too few batches).
    pub rhat: Option<f64>,
    /// Bulk effective sample size, in batches.
    pub ess: Option<f64>,
    /// The block's share of all deposits.
    pub share: f64,
}

/// The diagnostics of a set of chains on a block grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Mixing {
    pub grid: BlockGrid,
    pub chains: usize,
    /// Batches per chain the diagnostics use and the steps in each.
    pub batches: usize,
    pub batch_steps: u64,
    pub blocks: Vec<BlockMixing>,
}

impl Mixing {
    /// The diagnostics of `traces` (one per chain) on `grid`: every chain's batches brought to
    /// the longest batch any chain has, and cut to the fewest batches any chain has.
    pub fn of(grid: BlockGrid, traces: &[ChainTrace]) -> Mixing {
        let batch_steps = traces.iter().map(|t| t.batch_steps).max().unwrap_or(1);
        let series: Vec<Vec<f32>> = traces
            .iter()
            .map(|t| t.coarsened((batch_steps / t.batch_steps.max(1)).max(1) as usize))
            .collect();
        let nb = grid.len().max(1);
        let batches = series.iter().map(|s| s.len() / nb).min().unwrap_or(0);
        let blocks = (0..grid.len())
            .map(|k| {
                let chains: Vec<Vec<f64>> = series
                    .iter()
                    .map(|s| (0..batches).map(|i| s[i * nb + k] as f64).collect())
                    .collect();
                let total: f64 = chains.iter().flatten().sum();
                let n = (chains.len() * batches).max(1) as f64;
                let share = total / n;
                let visited = share > 0.0;
                BlockMixing {
                    rhat: if visited { rhat(&chains) } else { None },
                    ess: if visited { bulk_ess(&chains) } else { None },
                    share,
                }
            })
            .collect();
        Mixing {
            grid,
            chains: traces.len(),
            batches,
            batch_steps,
            blocks,
        }
    }

    /// Whether block `b` has not mixed: R-hat above [`RHAT_THRESHOLD`] or bulk ESS below
    /// [`MIN_ESS_PER_CHAIN`] per chain.
    pub fn unmixed(&self, b: &BlockMixing) -> bool {
        b.rhat.is_some_and(|r| r > RHAT_THRESHOLD)
            || b.ess
                .is_some_and(|e| e < MIN_ESS_PER_CHAIN * self.chains as f64)
    }

    /// The blocks that have not mixed, worst R-hat first.
    pub fn unmixed_blocks(&self) -> Vec<usize> {
        let mut list: Vec<usize> = (0..self.blocks.len())
            .filter(|&k| self.unmixed(&self.blocks[k]))
            .collect();
        let key = |k: &usize| self.blocks[*k].rhat.unwrap_or(f64::INFINITY);
        list.sort_by(|a, b| key(b).total_cmp(&key(a)));
        list
    }

    /// The largest R-hat and its block.
    pub fn worst_rhat(&self) -> Option<(usize, f64)> {
        self.blocks
            .iter()
            .enumerate()
            .filter_map(|(k, b)| b.rhat.map(|r| (k, r)))
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The smallest bulk ESS and its block.
    pub fn least_ess(&self) -> Option<(usize, f64)> {
        self.blocks
            .iter()
            .enumerate()
            .filter_map(|(k, b)| b.ess.map(|e| (k, e)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The warning of integrator `name` when blocks have not mixed.
    pub fn warning(&self, name: &str) -> Option<String> {
        let bad = self.unmixed_blocks();
        let &first = bad.first()?;
        let b = self.blocks[first];
        let named: Vec<String> = bad
            .iter()
            .take(NAMED_BLOCKS)
            .map(|&k| self.grid.name(k))
            .collect();
        let more = bad.len().saturating_sub(NAMED_BLOCKS);
        Some(format!(
            "{name}: the chains have not mixed in {} of {} image blocks of {} pixels ({}{}): \
             worst split-R-hat {} (threshold {RHAT_THRESHOLD}), bulk ESS {} there (from {} \
             chains of {} batches); the image there is still converging: render more mutations \
             per pixel (--spp) or use more chains",
            bad.len(),
            self.blocks.len(),
            self.grid.size,
            named.join("; "),
            if more > 0 {
                format!("; {more} more")
            } else {
                String::new()
            },
            b.rhat.map_or("n/a".into(), |r| format!("{r:.3}")),
            b.ess.map_or("n/a".into(), |e| format!("{e:.0}")),
            self.chains,
            self.batches,
        ))
    }

    /// The `--json` value: the grid, the thresholds, the summary and the per-block rows.
    pub fn json(&self) -> serde_json::Value {
        let rows = |f: &dyn Fn(&BlockMixing) -> Option<f64>| {
            let cols = self.grid.cols.max(1) as usize;
            serde_json::Value::Array(
                self.blocks
                    .chunks(cols)
                    .map(|row| row.iter().map(|b| number(f(b))).collect())
                    .collect(),
            )
        };
        let worst = self.worst_rhat();
        let least = self.least_ess();
        let unmixed: Vec<serde_json::Value> = self
            .unmixed_blocks()
            .iter()
            .map(|&k| {
                let (c, r) = (k as u32 % self.grid.cols, k as u32 / self.grid.cols);
                serde_json::json!([c, r])
            })
            .collect();
        serde_json::json!({
            "block_size": self.grid.size,
            "blocks": [self.grid.cols, self.grid.rows],
            "chains": self.chains,
            "batches": self.batches,
            "batch_steps": self.batch_steps,
            "rhat_threshold": RHAT_THRESHOLD,
            "min_ess": MIN_ESS_PER_CHAIN * self.chains as f64,
            "rhat_max": number(worst.map(|w| w.1)),
            "ess_min": number(least.map(|l| l.1)),
            "unmixed": unmixed,
            "rhat": rows(&|b| b.rhat),
            "ess": rows(&|b| b.ess),
            "share": rows(&|b| Some(b.share)),
        })
    }

    /// The image header's attributes: the summary and the R-hat of every block.
    pub fn header(&self) -> Vec<(String, String)> {
        let fmt = |v: Option<f64>, p: usize| v.map_or("-".into(), |v| format!("{v:.p$}"));
        let rhat_rows: Vec<String> = self
            .blocks
            .chunks(self.grid.cols.max(1) as usize)
            .map(|row| {
                let v: Vec<String> = row.iter().map(|b| fmt(b.rhat, 3)).collect();
                v.join(" ")
            })
            .collect();
        let unmixed = self.unmixed_blocks();
        vec![
            (
                "mixing_blocks".into(),
                format!(
                    "{}x{} blocks of {} pixels, {} chains of {} batches of {} steps",
                    self.grid.cols,
                    self.grid.rows,
                    self.grid.size,
                    self.chains,
                    self.batches,
                    self.batch_steps
                ),
            ),
            (
                "mixing_rhat_max".into(),
                fmt(self.worst_rhat().map(|w| w.1), 4),
            ),
            (
                "mixing_ess_min".into(),
                fmt(self.least_ess().map(|l| l.1), 1),
            ),
            (
                "mixing_unmixed".into(),
                unmixed
                    .iter()
                    .map(|&k| self.grid.name(k))
                    .collect::<Vec<_>>()
                    .join("; "),
            ),
            ("mixing_rhat".into(), rhat_rows.join("\n")),
        ]
    }

    /// The summary line.
    pub fn line(&self) -> String {
        let worst = self.worst_rhat();
        format!(
            "  mixing: {} chains x {} batches of {} steps, {}x{} blocks of {} px: max split-R-hat {}{}, min bulk ESS {}, {} blocks not mixed",
            self.chains,
            self.batches,
            self.batch_steps,
            self.grid.cols,
            self.grid.rows,
            self.grid.size,
            worst.map_or("n/a".into(), |w| format!("{:.4}", w.1)),
            worst.map_or(String::new(), |w| format!(" ({})", self.grid.name(w.0))),
            self.least_ess()
                .map_or("n/a".into(), |l| format!("{:.0}", l.1)),
            self.unmixed_blocks().len()
        )
    }
}

/// A value for `--json`: a number, `"inf"` (chains stuck apart) or null (undefined).
fn number(v: Option<f64>) -> serde_json::Value {
    match v {
        Some(v) if v.is_infinite() => "inf".into(),
        v => serde_json::json!(v),
    }
}

/// The recorder an MCMC integrator keeps: the block grid and one trace per chain.
#[derive(Clone, Debug)]
pub struct Recorder {
    pub grid: BlockGrid,
    traces: Vec<ChainTrace>,
}

impl Recorder {
    pub fn new(scene: &Scene) -> Self {
        Recorder {
            grid: BlockGrid::of(scene),
            traces: Vec::new(),
        }
    }

    /// The traces of `n` chains, taken out for a pass (give them back with [`Recorder::put`]).
    pub fn take(&mut self, n: usize) -> Vec<ChainTrace> {
        let mut t = std::mem::take(&mut self.traces);
        t.resize_with(n, ChainTrace::default);
        t
    }

    pub fn put(&mut self, traces: Vec<ChainTrace>) {
        self.traces = traces;
    }

    /// The diagnostics so far (`None` before any step).
    pub fn mixing(&self) -> Option<Mixing> {
        (!self.traces.is_empty() && !self.grid.is_empty())
            .then(|| Mixing::of(self.grid, &self.traces))
    }

    /// What an integrator's statistics add: the `mixing` JSON value, its summary line, its
    /// warning and its header attributes.
    pub fn statistics(&self, name: &str, stats: &mut super::Statistics) {
        let Some(m) = self.mixing() else { return };
        if let Some(j) = stats.json.as_mut().and_then(|j| j.as_object_mut()) {
            j.insert("mixing".into(), m.json());
        }
        stats.lines.push(m.line());
        stats.warnings.extend(m.warning(name));
        stats.header.extend(m.header());
    }
}
