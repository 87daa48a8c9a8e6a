//! "Did you mean": the known word nearest a mistyped one. One rule for every suggestion the
//! body makes, a mapping file's keys, QoS profiles and type names ([`crate::mapping`]) as much
//! as message field paths ([`crate::messages`]), so that all of them suggest alike.
//!
//! A module of its own because both of those use it: kept in either, it would make each of
//! the two need the other.

/// The candidate closest to `word` (a typo or a shortening of it), if one is close enough to
/// suggest: by Damerau-Levenshtein distance, at most a third of the word's length (and at least
/// 1, but less than the whole word), or a candidate the word begins (`sensor` for
/// `sensor_data`).
pub fn closest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (word.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .map(|c| {
            let d = strsim::damerau_levenshtein(word, c);
            // A shortening counts as near, but a real typo nearer still wins a tie.
            (if word.len() >= 3 && c.starts_with(word) { d.min(limit) } else { d }, d, c)
        })
        // Near enough, and never a rewrite of the whole word (nothing is "near" an empty one).
        .filter(|(near, _, _)| *near <= limit && *near < word.chars().count())
        .min_by_key(|(near, d, _)| (*near, *d))
        .map(|(_, _, c)| c)
}
