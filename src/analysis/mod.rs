//! Terrain analysis: slope, aspect, curvature, hillshade, priority-flood depression filling, D8
//! and MFD flow accumulation, flood extent, spectra and realism metrics. Pure functions, no IO.
