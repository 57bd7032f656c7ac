"""The `vmj` command line. Its JSON output is a contract: other tools parse it.

`main(argv)` runs it. The commands are listed once, in `vmj.cli._app.COMMANDS`, each with the
module that defines it (`add_arguments(parser)`, `run(args) -> int`); a module is imported only
when its command is named, and JAX only when a command runs. `vmj fit` is defined by the fits
package (`fits._cli`), which uses the option helpers exported here.

Bad input prints one line `vmj: error: ...` to stderr and exits with status 2.
"""

from ._app import COMMANDS, main
from ._options import (
    count,
    emit,
    figure_path,
    input_file,
    number,
    output_path,
    parse_axis,
    parse_set,
)

__all__ = [
    "main",
    "COMMANDS",
    "number",
    "count",
    "parse_set",
    "parse_axis",
    "input_file",
    "output_path",
    "figure_path",
    "emit",
]
