#!/usr/bin/env python3
"""Lists C++ functions longer than a limit (default 80 lines), counted from the first line of the
signature to the closing brace, comments and blank lines included.

Usage: function_length.py [--max N] [--top K] PATH...   (PATH: files or folders; *.cpp *.hpp *.h)
Exit 0 when every function is within the limit, 1 when one is longer (each is listed), 2 on usage.

How it reads C++: comments, string/char literals (raw strings too) and preprocessor lines are blanked
(newlines kept), then braces are classified by the text before them at namespace/class scope:
`namespace`/`class`/`struct`/`union`/`enum`/`extern "C"` open a scope; a head with a parameter list
`(...)` (plus qualifiers, trailing return, constructor initializer list) or a lambda `[...](...)`
opens a function body, which is measured as a whole (lambdas and blocks inside count towards it);
anything else (brace initializers) is skipped. Checked against universal-ctags' end lines on
firmware/ (tests/layers/README.md).
"""
import os
import re
import sys

SCOPE_RE = re.compile(r'^(?:template\s*<.*?>\s*)?(?:\[\[.*?\]\]\s*)*'
                      r'(?:export\s+)?(namespace|class|struct|union|enum|extern)\b', re.S)
LAMBDA_RE = re.compile(r'\]\s*(?:\([^()]*(?:\([^()]*\)[^()]*)*\))?\s*'
                       r'(?:mutable|constexpr|noexcept|->\s*[\w:<>,\s*&]+)*\s*$', re.S)


def blank_non_code(text):
    """Comments, literals and preprocessor lines -> spaces (newlines kept)."""
    out = []
    i, n = 0, len(text)
    line_start = True
    while i < n:
        c = text[i]
        if line_start and c in ' \t':
            out.append(c)
            i += 1
            continue
        if line_start and c == '#':  # preprocessor line, with continuations
            while i < n and text[i] != '\n':
                if text[i] == '\\' and i + 1 < n and text[i + 1] == '\n':
                    out.append(' \n')
                    i += 2
                    continue
                out.append(' ')
                i += 1
            continue
        line_start = False
        if text.startswith('//', i):
            while i < n and text[i] != '\n':
                out.append(' ')
                i += 1
            continue
        if text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            out.append(re.sub(r'[^\n]', ' ', text[i:j]))
            i = j
            continue
        m = re.match(r'(?:u8|u|U|L)?R"([^()\\\s]{0,16})\(', text[i:i + 24])
        if m and (i == 0 or not (text[i - 1].isalnum() or text[i - 1] == '_')):
            end = ')' + m.group(1) + '"'
            j = text.find(end, i + m.end())
            j = n if j < 0 else j + len(end)
            out.append('""' + re.sub(r'[^\n]', ' ', text[i + 2:j]))
            i = j
            continue
        if c in '"\'':
            # a digit separator (1'000) is not a char literal
            if c == "'" and i > 0 and text[i - 1].isalnum() and i + 1 < n and text[i + 1].isalnum() \
                    and re.match(r"[0-9a-fA-FxXbB']", text[i - 1]):
                out.append(' ')
                i += 1
                continue
            j = i + 1
            while j < n and text[j] != c and text[j] != '\n':
                j += 2 if text[j] == '\\' else 1
            j = min(j + 1, n)
            out.append(c + ' ' * (j - i - 2) + c if j - i >= 2 else c)
            i = j
            continue
        if c == '\n':
            line_start = True
        out.append(c)
        i += 1
    return ''.join(out)


def strip_nested(head):
    """Removes the contents of (...), <...> is kept; used to find top-level '='."""
    depth, out = 0, []
    for ch in head:
        if ch == '(':
            depth += 1
        elif ch == ')':
            depth -= 1
            continue
        if depth == 0:
            out.append(ch)
    return ''.join(out)


def classify(head):
    h = head.strip()
    if not h:
        return 'other'
    if SCOPE_RE.match(h):
        return 'scope'
    if LAMBDA_RE.search(h) and '[' in h:
        return 'function'
    if ')' not in h:
        return 'other'
    top = strip_nested(re.sub(r'\boperator\s*(?:\(\s*\)|\[\s*\]|[^\s(]+)', 'operator', h))
    top = re.sub(r'^template\s*<.*?>', '', top, flags=re.S)
    # `T x = f(...)` at top level: an initializer, not a function body
    if re.search(r'(?<![<>!=])=(?!=)', top):
        return 'other'
    # a member's brace initializer in a constructor's initializer list: `X() : a_(1), b_{`
    tail = h[h.rfind(')') + 1:]
    if re.search(r'[\w>]\s*$', tail) and '->' not in tail and not re.fullmatch(
            r'(?:\s|const|noexcept|override|final|mutable|volatile|try|&)*', tail):
        return 'other'
    return 'function'


def name_of(head):
    h = re.sub(r'\s+', ' ', head.strip())
    m = re.search(r'([~\w:]+(?:\s*operator\s*[^\s(]+)?)\s*\(', h)
    if m:
        return m.group(1)
    return h[:60]


def functions(path):
    text = open(path, encoding='utf-8', errors='replace').read()
    code = blank_non_code(text)
    line_of = []  # offset -> line number, computed lazily via cumulative count
    stack = []    # entries: (kind, start_offset_of_head, name)
    head_start = 0
    result = []
    i, n = 0, len(code)
    while i < n:
        c = code[i]
        in_function = any(k == 'function' for k, _, _ in stack)
        if in_function:
            if c == '{':
                stack.append(('block', i, ''))
            elif c == '}':
                kind, start, name = stack.pop()
                if kind == 'function':
                    result.append((name, start, i))
                    head_start = i + 1
            i += 1
            continue
        if c == ';':
            head_start = i + 1
        elif c == '{':
            head = code[head_start:i]
            kind = classify(head)
            if kind == 'other':
                # a brace initializer: skip to its matching brace, keep the head running
                depth, j = 0, i
                while j < n:
                    if code[j] == '{':
                        depth += 1
                    elif code[j] == '}':
                        depth -= 1
                        if depth == 0:
                            break
                    j += 1
                i = j + 1
                continue
            start = head_start + (len(head) - len(head.lstrip()))
            stack.append((kind, start, name_of(head) if kind == 'function' else ''))
            head_start = i + 1
        elif c == '}':
            if stack:
                stack.pop()
            head_start = i + 1
        elif c == ':' and stack and stack[-1][0] == 'scope' and re.search(
                r'\b(public|private|protected)\s*$', code[head_start:i]):
            head_start = i + 1
        i += 1
    out = []
    for name, start, end in result:
        first = code.count('\n', 0, start) + 1
        last = code.count('\n', 0, end) + 1
        out.append((last - first + 1, first, last, name))
    return out


def sources(paths):
    for p in paths:
        if os.path.isdir(p):
            for root, _, files in os.walk(p):
                for f in sorted(files):
                    if f.endswith(('.cpp', '.hpp', '.h', '.cc')):
                        yield os.path.join(root, f)
        else:
            yield p


def main(argv):
    limit, top, paths = 80, 0, []
    args = list(argv)
    while args:
        a = args.pop(0)
        if a == '--max':
            limit = int(args.pop(0))
        elif a == '--top':
            top = int(args.pop(0))
        elif a.startswith('-'):
            print(__doc__, file=sys.stderr)
            return 2
        else:
            paths.append(a)
    if not paths:
        print(__doc__, file=sys.stderr)
        return 2
    rows = []
    for f in sorted(sources(paths)):
        for length, first, last, name in functions(f):
            rows.append((length, f, first, last, name))
    rows.sort(key=lambda r: (-r[0], r[1], r[2]))
    long_rows = [r for r in rows if r[0] > limit]
    for length, f, first, last, name in (rows[:top] if top else long_rows):
        mark = 'TOO LONG' if length > limit else 'ok'
        print(f'{length:4d} lines  {f}:{first}-{last}  {name}  {mark}')
    print(f'{len(rows)} functions read; {len(long_rows)} longer than {limit} lines'
          + (f'; the longest has {rows[0][0]}' if rows else ''))
    return 1 if long_rows else 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
