"""No product module unpickles a file any way but through ``motion.safe_load``.

The code of every product module (comments and strings left out) is searched for the
ways Python runs a file's pickle: ``allow_pickle=True`` (or any value but ``False``),
``pickle.load(``/``loads(``/``Unpickler(`` and their imports, ``joblib.load(``,
pandas' ``read_pickle(``, ``weights_only=False``, and ``torch.load(`` without
``weights_only=True``.
"""

import io
import re
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PRODUCT = ["motion", "generation", "rendering", "motion_metrics", "analysis", "studyapp", "benchmarks",
           "scripts", "manage.py"]
FORBIDDEN = [
    (re.compile(r"allow_pickle=(?!False\b)"), "allow_pickle other than False"),
    (re.compile(r"\bpickle\.(load|loads|Unpickler)\("), "pickle's unpickler"),
    (re.compile(r"\bfrom (c?pickle|_pickle|dill|cloudpickle) import .*\b(load|loads|Unpickler)\b"),
     "pickle's unpickler, imported"),
    (re.compile(r"\b(joblib|dill|cloudpickle)\.load"), "joblib's (or dill's) loader"),
    (re.compile(r"\bread_pickle\("), "pandas' read_pickle"),
    (re.compile(r"weights_only=(?!True\b)"), "weights_only other than True"),
]
TORCH_LOAD = re.compile(r"\btorch\.load\(")
NOT_CODE = {tokenize.COMMENT, tokenize.STRING, tokenize.NL, tokenize.INDENT, tokenize.DEDENT,
            tokenize.ENCODING} | {getattr(tokenize, name) for name in (
                "FSTRING_START", "FSTRING_MIDDLE", "FSTRING_END") if hasattr(tokenize, name)}


def code_of(text: str) -> list[str]:
    """Return the source's logical lines as code only: no comments or strings, names apart
    by one space, no space around punctuation."""
    lines, current = [], []
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type in NOT_CODE:
            continue
        if token.type in (tokenize.NEWLINE, tokenize.ENDMARKER):
            if current:
                lines.append(re.sub(r" ?([^\w ]) ?", r"\1", " ".join(current)))
            current = []
            continue
        current.append(token.string)
    return lines


def problems_in(text: str) -> list[str]:
    """Return what in ``text`` (Python source) would unpickle a file unsafely."""
    found = []
    for line in code_of(text):
        for pattern, what in FORBIDDEN:
            if pattern.search(line):
                found.append(f"{what}: {line}")
        for call in TORCH_LOAD.finditer(line):
            depth, end = 0, call.end() - 1
            for end in range(call.end() - 1, len(line)):
                depth += {"(": 1, ")": -1}.get(line[end], 0)
                if depth == 0:
                    break
            if "weights_only=True" not in line[call.start(): end + 1]:
                found.append(f"torch.load without weights_only=True: {line}")
    return found


def product_files() -> list[Path]:
    files = []
    for name in PRODUCT:
        path = ROOT / name
        files += sorted(path.rglob("*.py")) if path.is_dir() else [path]
    return files


def test_product_code_never_unpickles_a_file_unsafely():
    files = product_files()
    assert len(files) > 100 and ROOT / "motion" / "safe_load" / "unpickler.py" in files
    found = [f"{path.relative_to(ROOT)}: {problem}" for path in files
             for problem in problems_in(path.read_text(encoding="utf-8"))]
    assert found == []


def test_the_search_finds_every_unsafe_way():
    unsafe = '''
import pickle, joblib, torch
from pickle import loads as restore
x = np.load(path, allow_pickle=True)
y = np.load(path, allow_pickle=flag)
z = pickle.load(open(path, "rb"))
w = pickle.loads(data)
u = pickle.Unpickler(handle).load()
v = joblib.load(path)
t = torch.load(path, map_location="cpu",
               weights_only=False)
s = torch.load(path)
r = pd.read_pickle(path)
'''
    assert len(problems_in(unsafe)) == 11
    safe = '''
# pickle.load(path) and allow_pickle=True in a comment
"""np.load(path, allow_pickle=True) in a docstring"""
x = np.load(path, allow_pickle=False)
m = torch.load(path, map_location="cpu", weights_only=True)
'''
    assert problems_in(safe) == []
