"""Exit statuses of the ``legbench`` command."""

EXIT_OK = 0
EXIT_FAILURE = 1  # a regression (check) or an unreachable point (model ik)
EXIT_USER_ERROR = 2  # bad input: nothing was run or written
EXIT_BACKEND_FAILED = 3  # a backend failed or diverged; the others' results are written
EXIT_IO_ERROR = (
    4  # a write or read of the file system failed (full disk, read-only, permissions); the previous result is intact
)
EXIT_INTERRUPTED = 130
EXIT_OUTPUT_CLOSED = 141  # 128 + SIGPIPE: the reader of stdout went away (`legbench ... | head`), quietly
