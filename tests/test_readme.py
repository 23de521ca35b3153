"""The README's example adapter runs as written and its method scores on the benchmark."""
import re
from pathlib import Path

from benchmark.aggregate import aggregate
from benchmark.evaluator import run_benchmark
from tests.bench_fixtures import make_bench_dataset

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_adapter_example_plugs_in(small_zoo, tmp_path, monkeypatch):
    import benchmark.registry as registry

    monkeypatch.setattr(registry.METHODS, "_runtime", dict(registry.METHODS._runtime))  # the example's name stays in this test
    code = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    exec(compile(code, "README.md", "exec"), {})
    data = make_bench_dataset(small_zoo, tmp_path / "data", h2h_poses=2, cct_pairs=2, cct_poses=1)
    run_benchmark(data, ["my_method"], ("h2h", "cct"), tmp_path / "res", progress=False)
    entries = aggregate(tmp_path / "res")["protocols"]
    assert all(e[0]["method"] == "my_method" and e[0]["complete"] for e in entries.values())


def test_readme_commands_name_real_subcommands():
    from mimicbench.cli import build_parser

    parser = build_parser()
    blocks = re.findall(r"```(?!python)\w*\n(.*?)```", README.read_text(), re.S)
    lines = [m for b in blocks for m in re.findall(r"^mimicbench (.+?)(?:\s{2,}#|$)", b, re.M)]
    assert len(lines) >= 8
    for line in lines:
        words = [w for w in line.split() if not w.startswith("-")][:2]
        try:
            parser.parse_args(words + ["--help"])
        except SystemExit as exc:
            assert exc.code == 0, line
