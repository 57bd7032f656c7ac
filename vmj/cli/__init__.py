"""The `vmj` command line. Its JSON output is a contract: other tools parse it.

`main(argv)` runs it. The commands are listed once, in `vmj.cli._app.COMMANDS`, each with the
module that defines it (`add_arguments(parser)`, `run(args) -> int`); a module is imported only
when its command is named, and JAX only when a command runs. `vmj fit` is defined by the fits
package (`fits._cli`), which uses the option helpers exported here.

Bad input prints one line `vmj: error: ...` to stderr and exits with status 2.

`enable_exported_cache(path)` keeps the exported programs of the compiled entry points in
`path`, so that a new process skips tracing them (the `vmj` command switches it on beside its
compilation cache; `exported_jit` is the decorator of those entry points, used by fits too).
"""

from .._exported import enable_exported_cache, exported_jit
from ._app import COMMANDS, main
from ._options import (
    Joined,
    count,
    emit,
    figure_path,
    input_file,
    jsonable,
    name_list,
    number,
    output_path,
    parse_axis,
    parse_set,
)

__all__ = [
    "main",
    "COMMANDS",
    "enable_exported_cache",
    "exported_jit",
    "number",
    "count",
    "parse_set",
    "parse_axis",
    "input_file",
    "output_path",
    "figure_path",
    "emit",
    "jsonable",
    "name_list",
    "Joined",
]
