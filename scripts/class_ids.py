#!/usr/bin/env python3
"""Class ids out of tims/ (issue 19 item 1): rewrites uses of tims::classes::k<Class>
into rack::class_ids::k<Class> (rack/components/class_ids.h, generated from the
rack_add_class declarations by cmake/RackClass.cmake), or checks that none is left.

  scripts/class_ids.py           rewrite the tracked C++ files in place: the constant
                                 (class_ids::kX inside namespace rack, rack::class_ids::kX
                                 elsewhere), the #include, a `namespace classes =
                                 tims::classes;` alias nothing uses any more; then
                                 clang-format-14 over the files it changed
  scripts/class_ids.py --check   change nothing; exit 1 and name each file that still uses
                                 a class id of tims/ (anything but kExecutor, kTool,
                                 kFirstUser), or a file under tims/ that names a
                                 component class (the ctest `class_ids_check`)

Rerun it after merging a branch that still uses tims::classes: the rewrite is
idempotent. The class names and ids come from the rack_add_class calls of
components/*/CMakeLists.txt, parsed here the way RackClass.cmake names them
(kScan2d for Scan2D, kMcl for MCL).
"""
import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..'))
TIMS_OWN = {'kExecutor', 'kTool', 'kFirstUser'}
INCLUDE = '#include "rack/components/class_ids.h"'
USE = re.compile(r'\b(?:rack::)?(?:tims::)?classes::(k[A-Za-z0-9_]+)\b')
ALIAS = re.compile(r'^[ \t]*namespace classes = (?:rack::)?tims::classes;[ \t]*\n', re.M)


def constant_name(name):
    """kChassis for Chassis, kScan2d for Scan2D, kMcl for MCL (_rack_id_constant)."""
    out, after_upper = 'k', False
    for c in name:
        if 'A' <= c <= 'Z':
            if after_upper:
                c = c.lower()
            after_upper = True
        else:
            after_upper = c.isdigit()
        out += c
    return out


def cmake_calls(text, command):
    """The argument tokens of each `command(...)` in a CMake file (quotes kept whole)."""
    for m in re.finditer(r'\b%s\s*\(' % command, text):
        i, depth, tokens, tok = m.end(), 1, [], ''
        while i < len(text) and depth > 0:
            c = text[i]
            if c == '"':
                j = i + 1
                while j < len(text) and text[j] != '"':
                    j += 2 if text[j] == '\\' else 1
                tok += text[i + 1:j]
                i = j + 1
                continue
            if c == '#' and not tok:
                i = text.find('\n', i)
                i = len(text) if i < 0 else i
                continue
            if c == '(':
                depth += 1
            elif c == ')':
                depth -= 1
            if c.isspace() or depth == 0:
                if tok:
                    tokens.append(tok)
                tok = ''
            else:
                tok += c
            i += 1
        yield tokens


def declared_classes():
    """{constant: id} and the set of class and TiMS names, from components/*/CMakeLists.txt."""
    ids, names = {}, set()
    components = os.path.join(ROOT, 'components')
    for folder in sorted(os.listdir(components)):
        path = os.path.join(components, folder, 'CMakeLists.txt')
        if not os.path.isfile(path):
            continue
        for tokens in cmake_calls(open(path).read(), r'rack_add_(?:opencv_)?class'):
            args = dict(zip(tokens, tokens[1:]))
            name, iface = args.get('NAME'), args.get('INTERFACE') or args.get('NAME')
            if not name or 'ID' not in args:
                continue
            names.update({name, iface})
            ids[constant_name(iface)] = int(args['ID'], 0)
    return ids, names


def tracked(*patterns):
    out = subprocess.run(['git', 'ls-files', '--', *patterns], cwd=ROOT, check=True, capture_output=True, text=True)
    return [f for f in out.stdout.splitlines() if f]


def add_include(text):
    if INCLUDE in text:
        return text
    lines = text.split('\n')
    quoted = [i for i, l in enumerate(lines) if l.startswith('#include "rack/')]
    if not quoted:
        quoted = [i for i, l in enumerate(lines) if l.startswith('#include "')]
    if not quoted:
        quoted = [i for i, l in enumerate(lines) if l.startswith('#include')]
    at = quoted[-1] + 1 if quoted else 0
    for i in quoted:  # the alphabetical place among the project's includes
        if lines[i].startswith('#include "rack/') and lines[i] > INCLUDE:
            at = i
            break
    lines.insert(at, INCLUDE)
    return '\n'.join(lines)


def rewrite(path, ids, problems):
    text = open(os.path.join(ROOT, path)).read()
    in_rack = re.search(r'^namespace rack\b', text, re.M) is not None

    def replace(m):
        constant = m.group(1)
        if constant in TIMS_OWN:
            return m.group(0)
        if constant not in ids:
            problems.append('%s: %s is no declared class (rack_add_class in components/)' % (path, m.group(0)))
            return m.group(0)
        return ('class_ids::' if in_rack else 'rack::class_ids::') + constant

    new = USE.sub(replace, text)
    if new == text:
        return False
    if not re.search(r'(?<![A-Za-z0-9_])classes::', new):
        new = ALIAS.sub('', new)
    new = add_include(new)
    with open(os.path.join(ROOT, path), 'w') as f:
        f.write(new)
    return True


def check(ids, names):
    bad = []
    for path in tracked('*.cpp', '*.h', '*.hpp', '*.cc'):
        text = open(os.path.join(ROOT, path), errors='replace').read()
        for m in USE.finditer(text):
            if m.group(1) not in TIMS_OWN:
                bad.append('%s: %s (scripts/class_ids.py rewrites it)' % (path, m.group(0)))
                break
    word = re.compile(r'\b(%s)\b' % '|'.join(sorted(map(re.escape, names), key=len, reverse=True)))
    for path in tracked('tims/'):
        text = open(os.path.join(ROOT, path), errors='replace').read()
        in_classes = False  # inside tims' `namespace classes {`: only its own ids
        for n, line in enumerate(text.split('\n'), 1):
            m = word.search(line)
            if m:
                bad.append('%s:%d: names the class %s (tims/ knows no class)' % (path, n, m.group(1)))
            if re.match(r'\s*namespace classes\b', line):
                in_classes = True
            elif in_classes and line.startswith('}'):
                in_classes = False
            elif in_classes:
                c = re.search(r'\b(k[A-Za-z0-9_]+)\s*=', line)
                if c and c.group(1) not in TIMS_OWN:
                    bad.append('%s:%d: the class id %s (rack/components/class_ids.h has them)' % (path, n, c.group(1)))
    return bad


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else ''
    if mode not in ('', '--check'):
        print(__doc__, file=sys.stderr)
        return 2
    if subprocess.run(['git', 'rev-parse', '--is-inside-work-tree'], cwd=ROOT, capture_output=True).returncode != 0:
        print('class_ids: not a git checkout: the file list comes from git ls-files', file=sys.stderr)
        return 77
    ids, names = declared_classes()
    if not ids:
        print('class_ids: no rack_add_class found under components/', file=sys.stderr)
        return 1
    if mode == '--check':
        bad = check(ids, names)
        for b in bad:
            print(b, file=sys.stderr)
        print('class_ids: %d problem(s) in %d declared classes' % (len(bad), len(names)))
        return 1 if bad else 0
    problems, changed = [], []
    for path in tracked('*.cpp', '*.h', '*.hpp', '*.cc'):
        if path.startswith('tims/'):
            continue
        if rewrite(path, ids, problems):
            changed.append(path)
    clang_format = os.environ.get('CLANG_FORMAT', 'clang-format-14')
    if changed and shutil.which(clang_format):
        subprocess.run([clang_format, '-i', '--style=file', *changed], cwd=ROOT, check=True)
    for p in changed:
        print(p)
    for p in problems:
        print(p, file=sys.stderr)
    print('class_ids: rewrote %d file(s)%s' % (len(changed), '' if shutil.which(clang_format) else
                                              ' (no %s: run scripts/format.sh)' % clang_format))
    return 1 if problems else 0


if __name__ == '__main__':
    sys.exit(main())
