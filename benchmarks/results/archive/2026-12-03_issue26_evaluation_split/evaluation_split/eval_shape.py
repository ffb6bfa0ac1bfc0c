import sys
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parents[3]))  # benchmarks/, for code_shape
from code_shape import functions
for root in sys.argv[1:]:
    root = Path(root)
    print(f"## {root}")
    files = sorted(list((root / "mushrooms" / "evaluation").rglob("*.py")) + [root / "mushrooms/tool/bench.py", root / "mushrooms/tool/study.py"] + ([root / "mushrooms/config.py"] if (root / "mushrooms/config.py").exists() else []))
    tot = 0
    for f in files:
        n = len(f.read_text().splitlines()); tot += n
        fs = sorted(functions(f), reverse=True)
        top = ", ".join(f"{name} {l}" for l, name in fs[:2])
        print(f"  {n:5d}  {f.relative_to(root)}  ({len(fs)} functions; longest: {top})")
    allf = sorted((l, f"{f.relative_to(root)}:{name}") for f in files for l, name in functions(f))
    print(f"  total {tot} lines in {len(files)} modules; functions > 60 lines: {[x for x in allf if x[0] > 60][::-1]}")
