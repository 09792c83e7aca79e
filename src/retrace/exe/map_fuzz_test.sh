#!/usr/bin/env bash
# Fuzz test of the files retrace reads that users copy around: maps and camera files (issue 18).
# A small map is taught from simulator frames; mutants of it (bytes flipped in the pages of each table, pages zeroed,
# swapped or cut off, header fields, rows deleted or set to odd values by SQL, a schema damaged) and of its camera
# YAML (values, lines, bytes) are run through `inspect` and `repeat` (maps) and `camera-info` and `repeat --camera`
# (camera files). Each run must exit 0, or 1 with one error line "retrace: error: ..." that names the mutated file,
# says something and holds printable text only; never a signal, a hang or an empty message.
# A map that inspect refuses must be refused by repeat too (one check on open for every command).
# Usage: map_fuzz_test.sh RETRACE_BINARY [MAP_MUTANTS [CAMERA_MUTANTS [SEED]]]   (deterministic for a seed)
# RETRACE_FUZZ_KEEP=DIR copies failing mutants there; RETRACE_FUZZ_LOG=FILE appends every run's exit code and last
# line of stderr.
set -u
bin=$1
map_mutants=${2:-70}
camera_mutants=${3:-30}
seed=${4:-18}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
start=$SECONDS

"$bin" sim render --out "$tmp/teach" --frames 16 --width 128 --height 96 --quiet >/dev/null &&
  "$bin" sim render --out "$tmp/repeat" --variant repeat --frames 3 --width 128 --height 96 --quiet >/dev/null &&
  "$bin" teach --sequence "$tmp/teach" --map "$tmp/map.db" --no-progress >/dev/null 2>&1 ||
  { echo "FAIL: cannot make the map to mutate"; exit 1; }

mkdir "$tmp/mutants"
python3 - "$tmp/map.db" "$tmp/teach/camera.yaml" "$tmp/mutants" "$map_mutants" "$camera_mutants" "$seed" <<'EOF' ||
import os, random, shutil, sqlite3, struct, sys

map_path, camera_path, out, map_count, camera_count, seed = sys.argv[1:7]
rng = random.Random(int(seed))
original = open(map_path, 'rb').read()
page_size = struct.unpack('>H', original[16:18])[0]
with sqlite3.connect(map_path) as db:
    pages = {}
    for name, page in db.execute('SELECT name, pageno FROM dbstat'):
        pages.setdefault(name, []).append(page)
    tables = {name: [c[1] for c in db.execute(f'PRAGMA table_info({name})')]
              for (name,) in db.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}

def odd_value():
    return rng.choice([None, 0, -1, 1, 7, 2**31, -2**63, 2**63 - 1, 1e308, -1e-308, 0.5, 'x', '', 'nan',
                       b'', b'\x00\xff\x7f\x80', os.urandom(rng.randint(1, 100)).hex(), rng.randint(-3, 40)])

def mutate_bytes(data):
    data = bytearray(data)
    kind = rng.choice(['table', 'table', 'table', 'anywhere', 'header', 'zero-page', 'swap-pages', 'truncate'])
    if kind == 'table':  # flip bytes in the pages of one table or index (not only the key-images' pages)
        name = rng.choice(sorted(pages))
        page = rng.choice(pages[name]) - 1
        for _ in range(rng.randint(1, 8)):
            data[page * page_size + rng.randrange(page_size)] = rng.randrange(256)
        return data, f'bytes in a page of {name}'
    if kind == 'anywhere':
        for _ in range(rng.randint(1, 16)):
            data[rng.randrange(len(data))] = rng.randrange(256)
        return data, 'bytes anywhere'
    if kind == 'header':
        data[rng.randrange(100)] = rng.randrange(256)
        return data, 'a byte of the header'
    pages_total = len(data) // page_size
    if kind == 'zero-page':
        page = rng.randrange(pages_total)
        data[page * page_size:(page + 1) * page_size] = bytes(page_size)
        return data, f'page {page + 1} zeroed'
    if kind == 'swap-pages':
        a, b = rng.sample(range(pages_total), 2)
        pa, pb = bytes(data[a * page_size:(a + 1) * page_size]), bytes(data[b * page_size:(b + 1) * page_size])
        data[a * page_size:(a + 1) * page_size], data[b * page_size:(b + 1) * page_size] = pb, pa
        return data, f'pages {a + 1} and {b + 1} swapped'
    cut = rng.choice([rng.randrange(len(data)), rng.randrange(pages_total) * page_size])
    return data[:cut], f'truncated to {cut} bytes'

WITHOUT_ROWID = {'observations': 'node_id', 'arc_points': 'arc_id', 'node_scales': 'node_id'}  # their first key

def mutate_sql(path):
    db = sqlite3.connect(path)
    db.execute('PRAGMA foreign_keys = OFF')
    table = rng.choice(sorted(tables))
    kind = rng.choice(['update', 'update', 'update', 'delete', 'dangle', 'schema', 'drop', 'pragma'])
    if kind == 'update':
        column = rng.choice(tables[table])
        # Rows chosen by the seeded generator, not SQLite's random(): the same mutants on every run. The tables
        # WITHOUT ROWID get every fifth row by their first key.
        if table in WITHOUT_ROWID:
            db.execute(f'UPDATE {table} SET {column} = ? WHERE ({WITHOUT_ROWID[table]} + ?) % 5 = 0',
                       (odd_value(), rng.randrange(5)))
        else:
            rowids = [r for (r,) in db.execute(f'SELECT rowid FROM {table} ORDER BY rowid')]
            if rowids:
                db.execute(f'UPDATE {table} SET {column} = ? WHERE rowid = ?', (odd_value(), rng.choice(rowids)))
        what = f'{table}.{column} set to an odd value'
    elif kind == 'delete':
        db.execute(f'DELETE FROM {table} WHERE ({WITHOUT_ROWID.get(table, "rowid")} + ?) % 3 = 0', (rng.randrange(3),))
        what = f'rows of {table} deleted'
    elif kind == 'dangle':
        table, column = rng.choice([('arcs', 'from_node'), ('arcs', 'to_node'), ('node_features', 'node_id'),
                                    ('arc_point_lists', 'arc_id'), ('node_scales', 'arc_in'), ('node_scales', 'node_id')])
        db.execute(f'UPDATE {table} SET {column} = {column} + ?', (rng.choice([1, 1000, -1]),))
        what = f'{table}.{column} shifted'
    elif kind == 'schema':
        db.execute('PRAGMA writable_schema = ON')
        (sql,) = db.execute('SELECT sql FROM sqlite_master WHERE name = ?', (table,)).fetchone()
        i = rng.randrange(len(sql))
        sql = sql[:i] + rng.choice(['\x01\n\x1b[31m', '\u00e9', ')', ' NOT NULL', '']) + sql[i + rng.randint(0, 3):]
        db.execute('UPDATE sqlite_master SET sql = ? WHERE name = ?', (sql, table))
        what = f'schema of {table} damaged'
    elif kind == 'drop':
        db.execute(rng.choice([f'DROP TABLE {table}', f'ALTER TABLE {table} RENAME TO {table}_old',
                               f'ALTER TABLE {table} RENAME COLUMN {rng.choice(tables[table])} TO renamed']))
        what = f'{table} dropped or renamed'
    else:
        name = rng.choice(['user_version', 'application_id'])
        db.execute(f'PRAGMA {name} = {rng.choice([0, 2, 3, -1, 99])}')
        what = f'{name} changed'
    db.commit()
    db.close()
    return what

with open(os.path.join(out, 'maps.txt'), 'w') as listing:
    for i in range(int(map_count)):
        path = os.path.join(out, f'map{i:03d}.db')
        if rng.random() < 0.55:
            data, what = mutate_bytes(original)
            open(path, 'wb').write(bytes(data))
        else:
            shutil.copyfile(map_path, path)
            try:
                what = mutate_sql(path)
            except sqlite3.Error as e:  # a mutation SQLite itself refuses: keep the copy as it is
                what = f'SQL mutation refused ({e})'
        listing.write(f'{path}\t{what}\n')

camera_lines = open(camera_path, encoding='ascii').read().splitlines(keepends=True)

def odd_number():
    return rng.choice(['0', '-1', '1e308', '-1e308', 'nan', '.inf', '-.inf', 'abc', '', '1e-300', '3', '99999999999',
                       '[1, 2]', '{a: 1}', '"7"', '~'])

with open(os.path.join(out, 'cameras.txt'), 'w') as listing:
    for i in range(int(camera_count)):
        lines = list(camera_lines)
        kind = rng.choice(['value', 'value', 'list-value', 'list-length', 'delete-line', 'duplicate-line',
                           'swap-lines', 'truncate', 'bytes', 'model'])
        if kind in ('value', 'model'):
            keyed = [j for j, l in enumerate(lines) if ':' in l and not l.startswith('#')]
            j = rng.choice(keyed)
            key = lines[j].split(':')[0]
            value = odd_number() if kind == 'value' else rng.choice(['fisheye', 'equidistant', 'rational_polynomial',
                                                                      'plumb_bob ', '\u00e9', '0'])
            if kind == 'model':
                j = next(j for j, l in enumerate(lines) if l.startswith('distortion_model'))
                key = 'distortion_model'
            lines[j] = f'{key}: {value}\n'
            what = f'{key} = {value!r}'
        elif kind in ('list-value', 'list-length'):
            j = rng.choice([j for j, l in enumerate(lines) if 'data: [' in l])
            values = lines[j].split('[')[1].split(']')[0].split(', ')
            if kind == 'list-value':
                values[rng.randrange(len(values))] = odd_number()
            elif rng.random() < 0.5:
                values.pop(rng.randrange(len(values)))
            else:
                values.append('1')
            lines[j] = lines[j].split('[')[0] + '[' + ', '.join(values) + ']\n'
            what = f'line {j + 1}: {lines[j].strip()}'
        elif kind == 'delete-line':
            j = rng.randrange(len(lines))
            what = f'line {j + 1} deleted'
            del lines[j]
        elif kind == 'duplicate-line':
            j = rng.randrange(len(lines))
            lines.insert(j, lines[j])
            what = f'line {j + 1} twice'
        elif kind == 'swap-lines':
            a, b = rng.sample(range(len(lines)), 2)
            lines[a], lines[b] = lines[b], lines[a]
            what = f'lines {a + 1} and {b + 1} swapped'
        text = ''.join(lines).encode('utf-8')
        if kind == 'truncate':
            text = text[:rng.randrange(len(text))]
            what = f'truncated to {len(text)} bytes'
        elif kind == 'bytes':
            text = bytearray(text)
            for _ in range(rng.randint(1, 6)):
                text[rng.randrange(len(text))] = rng.randrange(256)
            what = 'bytes flipped'
        path = os.path.join(out, f'camera{i:03d}.yaml')
        open(path, 'wb').write(bytes(text))
        listing.write(f'{path}\t{what}\n')
EOF
  { echo "FAIL: cannot write the mutants"; exit 1; }

# run FILE WHAT COMMAND...: runs COMMAND (stdin closed, 60 s at most) and checks the outcome for the mutant FILE.
# Counts into runs and failures; leaves the exit code in last_rc. Uses $work (the worker's scratch files).
run() {
  local file=$1 what=$2
  shift 2
  local rc problem=''
  "$@" </dev/null >"$work.out" 2>"$work.err"
  rc=$?
  runs=$((runs + 1))
  [[ -n ${RETRACE_FUZZ_LOG:-} ]] && echo "$rc ${file##*/} $what :: $(tail -n 1 "$work.err")" >>"$RETRACE_FUZZ_LOG"
  if [[ $rc -eq 1 ]]; then
    local errors last
    errors=$(grep -c '^retrace: error: ' "$work.err")
    last=$(tail -n 1 "$work.err")
    if [[ $errors -ne 1 || $last != "retrace: error: "* ]]; then
      problem='not one error line, last on stderr'
    elif [[ $last != *"$file"* ]]; then
      problem='the error does not name the file'
    elif [[ -z ${last#retrace: error: $file} || -z ${last#retrace: error: $file: } ]]; then
      problem='empty message'
    elif ! iconv -f UTF-8 -t UTF-8 "$work.err" >/dev/null 2>&1 || LC_ALL=C grep -q '[[:cntrl:]]' "$work.err"; then
      problem='control characters or bytes that are not UTF-8 text on stderr'
    fi
  elif [[ $rc -ne 0 ]]; then
    problem="exit $rc"
    [[ $rc -eq 124 ]] && problem+=' (hung)'
    [[ $rc -gt 128 ]] && problem+=" (signal $((rc - 128)))"
  fi
  last_rc=$rc
  if [[ -n $problem ]]; then
    failures=$((failures + 1))
    echo "FAIL ${file##*/} ($what): $problem: ${*##*/}"
    LC_ALL=C sed -n '1,5{s/[^[:print:]]/?/g;p}' "$work.err"
    [[ -n ${RETRACE_FUZZ_KEEP:-} ]] && cp "$file" "$RETRACE_FUZZ_KEEP/"
  fi
}

# worker INDEX: runs every other mutant (two workers for two cores) and writes "runs failures" to $tmp/worker.INDEX.
worker() {
  local index=$1 n=0 file what inspect_rc
  work=$tmp/worker.$index
  runs=0
  failures=0
  last_rc=0
  while IFS=$'\t' read -r file what; do
    n=$((n + 1))
    [[ $((n % 2)) -eq $index ]] || continue
    run "$file" "$what" timeout 60 "$bin" inspect --map "$file"
    inspect_rc=$last_rc
    run "$file" "$what" timeout 60 "$bin" repeat --map "$file" --sequence "$tmp/repeat" --output "$work.csv" \
      --no-progress
    if [[ $inspect_rc -eq 1 && $last_rc -eq 0 ]]; then
      failures=$((failures + 1))
      echo "FAIL ${file##*/} ($what): inspect refused it, repeat used it"
      [[ -n ${RETRACE_FUZZ_KEEP:-} ]] && cp "$file" "$RETRACE_FUZZ_KEEP/"
    fi
  done <"$tmp/mutants/maps.txt"
  while IFS=$'\t' read -r file what; do
    n=$((n + 1))
    [[ $((n % 2)) -eq $index ]] || continue
    run "$file" "$what" timeout 60 "$bin" camera-info --camera "$file"
    run "$file" "$what" timeout 60 "$bin" repeat --map "$tmp/map.db" --sequence "$tmp/repeat" --camera "$file" \
      --output "$work.csv" --no-progress
  done <"$tmp/mutants/cameras.txt"
  echo "$runs $failures" >"$tmp/worker.$index"
}

worker 0 &
worker 1 &
wait
read -r runs0 failures0 <"$tmp/worker.0" || { echo "FAIL: worker 0 did not finish"; exit 1; }
read -r runs1 failures1 <"$tmp/worker.1" || { echo "FAIL: worker 1 did not finish"; exit 1; }
failures=$((failures0 + failures1))
echo "$((runs0 + runs1)) runs on $map_mutants map and $camera_mutants camera mutants (seed $seed) in" \
  "$((SECONDS - start)) s: $failures failed"
[[ $failures -eq 0 ]]
