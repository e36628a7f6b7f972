//! Input and output: scene files, structure files through chemfiles, CSV and JSON.

pub mod checkpoint;
pub mod csv;
pub mod energy_table;
pub mod forcefield;
pub mod manifest;
pub mod number;
pub mod scene;
pub mod structure;
pub mod study_csv;
pub mod study_file;
pub mod summary;
pub mod topology;
pub mod trajectory;
