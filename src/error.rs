//! Typed errors for every stage. Each variant carries where the problem is
//! (file, glTF path such as `meshes[3].primitives[0].indices`, config key), so
//! the binary can print one line that names it.

use std::path::PathBuf;

/// Everything that can go wrong in a bake.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The glTF could not be parsed, or is not valid glTF.
    #[error("{path}: not a valid glTF file: {message}")]
    Parse {
        /// The scene file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// The glTF parsed, but some part of it is unusable (bad indices,
    /// non-finite values, references leaving the scene's folder...).
    #[error("{path}: {location}: {message}")]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The glTF path of the offending element, e.g. `meshes[0].primitives[1].indices`.
        location: String,
        /// What is wrong with it.
        message: String,
    },
    /// The scene has nothing to bake.
    #[error("{path}: {message}")]
    Empty {
        /// The scene file.
        path: PathBuf,
        /// Why nothing can be baked.
        message: String,
    },
    /// A configuration value is out of range or unknown.
    #[error("config key `{key}`: {message}")]
    Config {
        /// The key, as written in `bake.toml` and on the command line.
        key: String,
        /// What is wrong with its value.
        message: String,
    },
    /// The UV unwrapper failed.
    #[error("lightmap unwrap failed: {0}")]
    Unwrap(String),
    /// A resource limit (memory, texels) would be exceeded.
    #[error("limit exceeded: {0}")]
    Limit(String),
    /// An output could not be encoded.
    #[error("{path}: could not encode output: {message}")]
    Encode {
        /// The output file.
        path: PathBuf,
        /// The encoder's message.
        message: String,
    },
    /// A shard's file (`radbake shard`) is missing, corrupt or not this
    /// plan's.
    #[error("shard {path}: {message}")]
    Shard {
        /// The slice or merge file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// A file a bake wrote (probes, say) that is read back is malformed.
    #[error("{path}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
    /// No usable graphics adapter (GPU or software): callers may treat this
    /// as "cannot run here" rather than as a failure.
    #[error("no graphics adapter: {0}")]
    NoAdapter(String),
    /// The GPU, its driver or a shader failed; a bake falls back to the CPU
    /// with a warning in `report.json`.
    #[error("{0}")]
    Device(String),
    /// Not a failure: a shard job wrote its part and stops there
    /// ([`crate::pipeline::shard::Sharding::checkpoint`]).
    #[error("this shard's part is written")]
    ShardDone,
}

impl Error {
    /// True when the error is the input's fault (bad scene or config) rather
    /// than the machine's (I/O) or ours; the CLI maps this to exit code 1.
    pub fn is_input_error(&self) -> bool {
        matches!(
            self,
            Error::Parse { .. }
                | Error::Shard { .. }
                | Error::Invalid { .. }
                | Error::Empty { .. }
                | Error::Config { .. }
                | Error::Limit(_)
                | Error::Malformed { .. }
        )
    }
}

/// [`Error::Device`] from a format string.
macro_rules! device_error {
    ($($t:tt)*) => {
        $crate::Error::Device(format!($($t)*))
    };
}
pub(crate) use device_error;

/// Return [`Error::Device`] from a format string.
macro_rules! device_bail {
    ($($t:tt)*) => {
        return Err($crate::error::device_error!($($t)*))
    };
}
pub(crate) use device_bail;

/// Result with the crate's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
