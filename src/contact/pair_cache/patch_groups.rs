//! The build's arranged pairs grouped by the patches of their two sides ([`Patches::of_side`]:
//! a pair's patch fall, [`Sweep::patch_fall`], depends only on them), each group with the
//! least slack its members had at the last sweep. A refilter (see [`super::super::sweep`])
//! looks again at a pair only where its slack `s` is below both the common fall `F` and its
//! patch fall `f_PQ`; a group whose least slack is at least `F` or at least `f_PQ` holds no
//! such pair, so the refilter takes one patch fall per group and reads the members of the
//! few groups that may hold one, instead of a record and a patch fall per near pair. (Pairs
//! within reach at the sweep, `s < 0`, are always looked at: their groups have `least < 0`.)
//!
//! [`Patches::of_side`]: super::super::patches::Patches::of_side
//! [`Sweep::patch_fall`]: super::super::sweep::Sweep::patch_fall

use rayon::prelude::*;

use super::super::sweep::SweptPair;

/// The build's arranged pairs by the patches of their sides.
#[derive(Default)]
pub(super) struct PatchGroups {
    /// The groups, by patch pair.
    groups: Vec<PatchGroup>,
    /// The members of every group, group after group, each group's in increasing pair order.
    members: Vec<Member>,
}

/// The pairs of one patch pair.
#[derive(Clone, Copy, Debug)]
pub(super) struct PatchGroup {
    /// The patches `[P, Q]` of the members' sides A and B.
    pub patches: [u32; 2],
    /// Its members are `members[start..end]`.
    start: u32,
    end: u32,
    /// The least slack (m) of its members that the last sweep looked at, `-inf` where one
    /// is NaN (a NaN slack keeps its pair, see `below` in [`super::filter`]).
    pub least: f32,
}

/// A member of a [`PatchGroup`]: a cached pair and its slack at the last sweep (m).
#[derive(Clone, Copy, Debug)]
pub(super) struct Member {
    pub pair: u32,
    pub slack: f32,
}

impl PatchGroups {
    /// Whether the pairs are grouped (a build empties the groups).
    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Forgets the groups (the pairs they were made for are gone).
    pub fn clear(&mut self) {
        self.groups.clear();
        self.members.clear();
    }

    /// Groups the pairs `0..patches.len()` by their sides' patches `patches[k]`.
    pub fn group(&mut self, patches: impl IndexedParallelIterator<Item = [u32; 2]>) {
        let mut keyed: Vec<(u64, u32)> = patches
            .enumerate()
            .map(|(k, [p, q])| ((u64::from(p) << 32) | u64::from(q), k as u32))
            .collect();
        keyed.par_sort_unstable();
        self.members.clear();
        self.members
            .par_extend(keyed.par_iter().map(|&(_, pair)| Member {
                pair,
                slack: f32::NAN,
            }));
        self.groups.clear();
        let mut start = 0;
        for (i, window) in keyed.windows(2).enumerate() {
            if window[0].0 != window[1].0 {
                self.groups.push(group_of(&keyed, start, i + 1));
                start = i + 1;
            }
        }
        if start < keyed.len() {
            self.groups.push(group_of(&keyed, start, keyed.len()));
        }
    }

    /// Records what a sweep saw of the pairs `..swept.len()` (the members beyond keep a NaN
    /// slack and count in no group's least).
    pub fn record(&mut self, swept: &[SweptPair]) {
        self.members.par_iter_mut().for_each(|m| {
            m.slack = swept.get(m.pair as usize).map_or(f32::NAN, |s| s.slack);
        });
        let (members, near) = (&self.members, swept.len());
        self.groups.par_iter_mut().for_each(|g| {
            g.least = members[g.start as usize..g.end as usize]
                .iter()
                .take_while(|m| (m.pair as usize) < near)
                .fold(f32::INFINITY, |least, m| {
                    if m.slack.is_nan() {
                        f32::NEG_INFINITY
                    } else {
                        least.min(m.slack)
                    }
                });
        });
    }

    /// The groups.
    pub fn groups(&self) -> &[PatchGroup] {
        &self.groups
    }

    /// The members of `group` below the pair `end`, in increasing pair order, with their
    /// slacks at the last sweep.
    pub fn members(&self, group: &PatchGroup, end: usize) -> impl Iterator<Item = &Member> {
        self.members[group.start as usize..group.end as usize]
            .iter()
            .take_while(move |m| (m.pair as usize) < end)
    }
}

/// The group of the sorted `keyed[start..end]` (one key), with no slack recorded.
fn group_of(keyed: &[(u64, u32)], start: usize, end: usize) -> PatchGroup {
    let key = keyed[start].0;
    PatchGroup {
        patches: [(key >> 32) as u32, key as u32],
        start: start as u32,
        end: end as u32,
        least: f32::NEG_INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every pair is in the group of its patches exactly once, in increasing order there, and
    /// a group's least is the least slack of its swept members (NaN counting as `-inf`,
    /// members beyond the sweep not at all).
    #[test]
    fn groups_hold_each_pair_once_with_the_least_swept_slack() {
        let patches: Vec<[u32; 2]> = (0..1000_u32).map(|k| [k % 7, (k * 13) % 5]).collect();
        let mut groups = PatchGroups::default();
        groups.group(patches.par_iter().copied());
        assert_eq!(groups.groups().len(), 35);
        let swept: Vec<SweptPair> = (0..900)
            .map(|k| SweptPair {
                slack: if k == 500 { f32::NAN } else { k as f32 },
            })
            .collect();
        groups.record(&swept);
        let mut seen = vec![0; 1000];
        for g in groups.groups() {
            let all: Vec<u32> = groups.members(g, usize::MAX).map(|m| m.pair).collect();
            assert!(all.windows(2).all(|w| w[0] < w[1]));
            let mut least = f32::INFINITY;
            for &k in &all {
                seen[k as usize] += 1;
                assert_eq!(patches[k as usize], g.patches);
                if k == 500 {
                    least = f32::NEG_INFINITY;
                } else if k < 900 {
                    least = least.min(k as f32);
                }
            }
            assert_eq!(g.least, least, "{:?}", g.patches);
            assert!(groups.members(g, 900).all(|m| m.pair < 900));
        }
        assert!(seen.iter().all(|&s| s == 1));
    }
}
