//! Layouts keep every object inside every camera's view, and the presets
//! follow the complexity ranking.

use nerflex_sim::capture::Split;
use nerflex_sim::procedural::complexity::stats;
use nerflex_sim::procedural::{
    arrange, ranked, view_cameras, Layout, ObjectKind, Preset, SCENE_RADIUS,
};
use proptest::prelude::*;

fn kinds_strategy() -> impl Strategy<Value = Vec<ObjectKind>> {
    prop::collection::vec(0..ObjectKind::ALL.len(), 1..7)
        .prop_map(|v| v.into_iter().map(|i| ObjectKind::ALL[i]).collect())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn every_object_projects_inside_every_view(
        kinds in kinds_strategy(),
        layout in prop::sample::select(vec![Layout::Row, Layout::Ring, Layout::Random]),
        seed in any::<u64>(),
    ) {
        let objects = arrange(&kinds, layout, seed, 1.0);
        prop_assert_eq!(objects.len(), kinds.len());
        let cams: Vec<_> = view_cameras(12, seed, Split::Train, 100)
            .into_iter()
            .chain(view_cameras(4, seed, Split::Test, 100))
            .collect();
        for o in &objects {
            prop_assert!(o.bounding_radius() <= SCENE_RADIUS + 1e-3);
            // Every surface cell of the object, placed, projects inside every view.
            let occ = stats(o.kind);
            let bounds = o.world_bounds();
            for &c in occ.surface.iter().step_by(7) {
                let p = o.placement.to_world(c);
                prop_assert!(bounds.contains(p));
                for cam in &cams {
                    let (x, y, _) = cam.project(p).unwrap();
                    prop_assert!(x > 0.0 && y > 0.0 && x < 100.0 && y < 100.0, "{} point {} at ({}, {})", o.name, p, x, y);
                }
            }
        }
        // Names are unique.
        let mut names: Vec<&str> = objects.iter().map(|o| o.name.as_str()).collect();
        names.sort();
        names.dedup();
        prop_assert_eq!(names.len(), objects.len());
    }
}

#[test]
fn presets_are_five_objects_from_the_ranking() {
    let r: Vec<ObjectKind> = ranked().into_iter().map(|(k, _)| k).collect();
    assert!(r.len() >= 10, "Scene 1 and Scene 2 do not overlap");
    assert_eq!(Preset::Scene1.kinds(), r[..5]);
    assert_eq!(Preset::Scene2.kinds(), r[r.len() - 5..]);
    for p in Preset::ALL {
        let k = p.kinds();
        assert_eq!(k.len(), 5, "{}", p.name());
        let mut u = k.clone();
        u.sort();
        u.dedup();
        assert_eq!(u.len(), 5, "{} has repeats", p.name());
    }
    // Scene 4 spans the range: the simplest and the most complex object.
    let s4 = Preset::Scene4.kinds();
    assert_eq!(s4[0], r[0]);
    assert_eq!(s4[4], r[r.len() - 1]);
}
