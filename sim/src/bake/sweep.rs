//! Many (g, p) bakes measured into a samples CSV (under construction).
