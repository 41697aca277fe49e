"""The edge between minifilm and the file system: what it reads, what it writes, and the names it
makes files from. Every reader and writer in minifilm goes through here.

    output_targets.py   what an output may replace (never a device, FIFO, read-only file or an input)
    atomic.py    atomic writes of files and folders: the old one or the new one, never half
    reading.py   reading only regular files, bounded; JSON and .npz archives checked before use
                 (each array's shape and dtype from its header, before its data is read)
    names.py     the one rule for names that come from data, and safe file names made from them
    lock.py      one writer at a time for a folder (a run, a style pack), whatever path names it
    state.py     the files minifilm keeps (a run's, a data set's, caches), which only their owner writes

This package imports nothing of minifilm but its errors, so every layer may use it.
"""
from minifilm.files.atomic import (atomic_directory, atomic_path, atomic_savez, atomic_write, atomic_write_text,
                                   check_writable, remove_stale_temporaries)
from minifilm.files.lock import FolderInUseError, folder_lock
from minifilm.files.names import (MAX_NAME_LENGTH, check_name, child_path, few, file_name, file_names, same_file_key,
                                  shared_file_names)
from minifilm.files.reading import (MAX_JSON_BYTES, MAX_NPZ_BYTES, Member, check_regular, open_regular, parse_json,
                                    read_json, read_npz, read_npz_member, read_regular_bytes)
from minifilm.files.state import owned_writes, state_of
from minifilm.files.output_targets import check_not_state, command_inputs, folder_target, note_input, output_target

__all__ = ["atomic_directory", "atomic_path", "atomic_savez", "atomic_write", "atomic_write_text", "check_writable",
           "remove_stale_temporaries", "FolderInUseError", "folder_lock", "MAX_NAME_LENGTH", "check_name",
           "child_path", "few", "file_name", "file_names", "same_file_key", "shared_file_names", "MAX_JSON_BYTES", "MAX_NPZ_BYTES", "Member", "check_regular",
           "open_regular", "parse_json", "read_json", "read_npz", "read_npz_member", "read_regular_bytes", "command_inputs",
           "folder_target", "check_not_state", "note_input", "output_target", "owned_writes", "state_of"]
