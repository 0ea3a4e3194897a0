//! The settings of voxel cone tracing (`[cones]`), declared once: cone shadows, ambient
//! occlusion and indirect light share the pyramid and the march (C. Crassin et al.,
//! "Interactive Indirect Illumination Using Voxel Cone Tracing", CGF 30(7), 2011).
//! The parser, the writer, the viewer's cone knobs, `voxlab ablate`, `ConeSettings::
//! default` and the listing take the type, default and range from here, through
//! [`GROUP`] (registered in `SETTING_GROUPS`).

pub mod march;
pub mod pyramid;

use super::{GroupSetting, Kind, Setting, SettingGroup};

/// The `[cones]` table: read by every technique that reads the pyramids.
pub const GROUP: SettingGroup = SettingGroup {
    table: "cones",
    title: "cone knobs",
    settings: CONE_SETTINGS,
    used: |f| f.cones(),
};

const fn float(
    key: &'static str,
    min: f64,
    max: f64,
    min_open: bool,
    default: f64,
    doc: &'static str,
) -> Setting {
    Setting {
        key,
        kind: Kind::Float {
            min,
            max,
            min_open,
            max_open: false,
        },
        default,
        unit: "",
        doc,
        sweep: &[],
    }
}

/// Every `[cones]` key, in the order the file lists them.
pub(crate) const CONE_SETTINGS: &[GroupSetting] = &[
    GroupSetting {
        setting: Setting {
            key: "levels",
            kind: Kind::Int {
                min: 0,
                max: crate::technique::cones::pyramid::MAX_LEVELS as i64,
            },
            default: 0.0,
            unit: "",
            doc: "pyramid levels; 0 chooses automatically",
            sweep: &[],
        },
        get: |s| s.cones.levels as f64,
        set: |s, v| s.cones.levels = v as u32,
    },
    GroupSetting {
        setting: float(
            "step_factor",
            0.0,
            4.0,
            true,
            0.5,
            "step length in footprints, dt = step_factor d",
        ),
        get: |s| s.cones.step_factor,
        set: |s, v| s.cones.step_factor = v,
    },
    GroupSetting {
        setting: float(
            "aperture_deg",
            0.0,
            120.0,
            false,
            5.0,
            "shadow-cone aperture for point lights, degrees",
        ),
        get: |s| s.cones.aperture_deg,
        set: |s, v| s.cones.aperture_deg = v,
    },
    GroupSetting {
        setting: float(
            "start_offset",
            0.0,
            16.0,
            false,
            1.0,
            "cone apex offset along the normal, voxels",
        ),
        get: |s| s.cones.start_offset,
        set: |s, v| s.cones.start_offset = v,
    },
    GroupSetting {
        setting: Setting {
            key: "ao_cones",
            kind: Kind::Int { min: 1, max: 64 },
            default: 8.0,
            unit: "",
            doc: "hemisphere cones for ambient occlusion and indirect light",
            sweep: &[],
        },
        get: |s| s.cones.ao_cones as f64,
        set: |s, v| s.cones.ao_cones = v as u32,
    },
    GroupSetting {
        setting: float(
            "ao_range",
            0.0,
            1e6,
            true,
            6.0,
            "range of the AO cones, voxels",
        ),
        get: |s| s.cones.ao_range,
        set: |s, v| s.cones.ao_range = v,
    },
    GroupSetting {
        setting: float(
            "indirect_strength",
            0.0,
            100.0,
            false,
            1.0,
            "scale of the one-bounce indirect term",
        ),
        get: |s| s.cones.indirect_strength,
        set: |s, v| s.cones.indirect_strength = v,
    },
];

/// The declaration of `[cones] key`.
pub(crate) fn cone_setting(key: &str) -> Option<&'static GroupSetting> {
    CONE_SETTINGS.iter().find(|c| c.setting.key == key)
}

/// The declared default of `[cones] key` (`ConeSettings::default` is made of these).
pub(crate) fn declared_default(key: &str) -> f64 {
    cone_setting(key)
        .unwrap_or_else(|| panic!("[cones] has no key {key}"))
        .setting
        .default
}
