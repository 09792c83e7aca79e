# shellcheck shell=bash
# Map data safety (issue 19 items 1, 2, 5; issue 18 item 5), sourced by cli_test.sh ($bin, $tmp, expect).
# A small map from simulator frames: teach writes MAP.incomplete and moves it onto MAP only when it succeeded, one
# teach at a time per map, and a damaged map is refused by every command with one line naming it.
ms=$tmp/map_safety
mkdir -p "$ms"
"$bin" sim render --out "$ms/drive" --frames 16 --width 128 --height 96 --quiet >/dev/null
"$bin" sim render --out "$ms/repeat" --variant repeat --frames 3 --width 128 --height 96 --quiet >/dev/null
"$bin" sim render --out "$ms/long" --frames 60 --width 128 --height 96 --quiet >/dev/null
expect safety-teach 0 'key-images' -- "$bin" teach --sequence "$ms/drive" --map "$ms/route.db" --no-progress
expect safety-nothing-left 0 '^route.db $' -- bash -c "ls '$ms' | grep -E '\.db' | tr '\n' ' '"

# A teach that fails with --overwrite (a frame of another size at position 10) leaves the old map byte-identical;
# what it taught until then is in route.db.incomplete, which inspect opens and calls incomplete.
mkdir -p "$ms/odd_frame"
cp "$ms"/drive/image_0/*.png "$ms/odd_frame/"
"$bin" sim render --out "$ms/small" --frames 1 --width 100 --height 80 --quiet >/dev/null
cp "$ms/small/image_0/000000.png" "$ms/odd_frame/000010.png"
before=$(md5sum <"$ms/route.db")
expect safety-failed-teach 1 \
  'teach failed: .*/route.db is unchanged; the map taught until the error is in .*/route.db.incomplete' -- \
  "$bin" teach --sequence "$ms/odd_frame" --camera "$ms/drive/calib.txt" --map "$ms/route.db" --overwrite --no-progress
expect safety-old-map-intact 0 '^same$' -- bash -c "[[ '$before' == \"\$(md5sum <'$ms/route.db')\" ]] && echo same"
expect safety-incomplete-inspect 0 'route.db.incomplete \(INCOMPLETE: its teach did not finish\)' -- \
  "$bin" inspect --map "$ms/route.db.incomplete"
expect safety-complete-inspect 0 'teach_state +complete' -- "$bin" inspect --map "$ms/route.db"

# --overwrite replaces retrace maps only.
echo "my notes" >"$ms/notes.txt"
expect safety-overwrite-foreign 1 "^retrace: error: $ms/notes.txt: not a retrace map; refusing to overwrite it" -- \
  "$bin" teach --sequence "$ms/drive" --map "$ms/notes.txt" --overwrite --no-progress
expect safety-foreign-intact 0 '^my notes$' -- cat "$ms/notes.txt"

# One writer at a time: while another process holds the map's lock, teach fails at once with one line.
flock -o "$ms/route.db.lock" sleep 5 &  # -o: the lock dies with flock itself
holder=$!
sleep 0.5
expect safety-locked 1 "^retrace: error: $ms/route.db: another retrace teach is writing this map now" -- \
  "$bin" teach --sequence "$ms/drive" --map "$ms/route.db" --overwrite --no-progress
kill "$holder" 2>/dev/null
wait "$holder" 2>/dev/null
# Two teaches at once on the same map: the second to start is refused (or, when the first was already done, both
# succeed one after the other); never two successes that lose a map, and the map left is whole.
"$bin" teach --sequence "$ms/long" --map "$ms/race.db" --overwrite --no-progress >"$ms/race1.out" 2>&1 &
first=$!
for _ in $(seq 100); do [[ -e $ms/race.db.lock ]] && break; sleep 0.02; done
"$bin" teach --sequence "$ms/long" --map "$ms/race.db" --overwrite --no-progress >"$ms/race2.out" 2>&1
second_rc=$?
wait "$first"
first_rc=$?
expect safety-race-outcome 0 '^ok$' -- bash -c "
  if [[ $first_rc -eq 0 && $second_rc -eq 1 ]] && grep -q 'another retrace teach is writing this map' '$ms/race2.out'
  then echo ok; else echo \"first $first_rc second $second_rc\"; cat '$ms/race2.out'; fi"
expect safety-race-map 0 'key-images +[1-9]' -- "$bin" inspect --map "$ms/race.db"

# A teach killed (kill -9) leaves the old map untouched and MAP.incomplete usable (and marked), and the next teach
# replaces it.
before=$(md5sum <"$ms/route.db")
"$bin" teach --sequence "$ms/long" --map "$ms/route.db" --overwrite --no-progress >/dev/null 2>&1 &
killed=$!
for _ in $(seq 200); do [[ -s $ms/route.db.incomplete-wal ]] && break; sleep 0.01; done
sleep 0.05
kill -9 "$killed" 2>/dev/null
wait "$killed" 2>/dev/null
expect safety-killed-old-intact 0 '^same$' -- bash -c "[[ '$before' == \"\$(md5sum <'$ms/route.db')\" ]] && echo same"
expect safety-killed-incomplete 0 'INCOMPLETE' -- "$bin" inspect --map "$ms/route.db.incomplete"
expect safety-teach-after-kill 0 'key-images' -- "$bin" teach --sequence "$ms/drive" --map "$ms/route.db" \
  --overwrite --no-progress
expect safety-nothing-left-after-kill 0 '^notes.txt race.db route.db $' -- \
  bash -c "ls '$ms' | grep -v '\.out$' | grep -E '\.(db|txt)' | tr '\n' ' '"

# A damaged map is refused by every command that reads maps, with one line naming the file.
damage() {  # damage COPY SQL: COPY of route.db changed by SQL, foreign keys off
  cp "$ms/route.db" "$ms/$1"
  python3 -c 'import sqlite3, sys
db = sqlite3.connect(sys.argv[1])
db.execute("PRAGMA foreign_keys = OFF")
db.executescript(sys.argv[2])
db.commit()' \
    "$ms/$1" "$2"
}
damage dangling.db 'UPDATE arcs SET to_node = 999 WHERE arc_id = 1;'
for command in inspect repeat drive; do
  case $command in
    inspect) args=(inspect --map "$ms/dangling.db") ;;
    repeat) args=(repeat --map "$ms/dangling.db" --sequence "$ms/repeat" --output "$ms/run.csv" --no-progress) ;;
    drive) args=(sim drive --map "$ms/dangling.db" --out "$ms/drive_out" --width 128 --height 96 --quiet) ;;
  esac
  expect "safety-dangling-arc-$command" 1 \
    "^retrace: error: $ms/dangling.db: corrupt map: arc 1 ends at missing node 999$" -- "$bin" "${args[@]}"
done
# A key-image whose stored JPEG is damaged (one byte in its middle) is refused with its node id: the map's
# checksums find what the JPEG decoder would let through.
damage bad_jpeg.db 'UPDATE nodes SET image = substr(image, 1, 600) || x'"'"'00'"'"' || substr(image, 602)
  WHERE node_id = 2;'
expect safety-corrupt-jpeg-inspect 1 \
  "^retrace: error: $ms/bad_jpeg.db: corrupt map: key-image of node 2 is corrupt \(checksum mismatch\)$" -- \
  "$bin" inspect --map "$ms/bad_jpeg.db"
expect safety-corrupt-jpeg-repeat 1 "^retrace: error: $ms/bad_jpeg.db: corrupt map: key-image of node 2 is corrupt" -- \
  "$bin" repeat --map "$ms/bad_jpeg.db" --sequence "$ms/repeat" --output "$ms/run.csv" --no-progress
# A schema damaged with control characters: SQLite quotes them, the message does not.
damage bad_schema.db "PRAGMA writable_schema = ON;
  UPDATE sqlite_master SET sql = 'CREATE TABLE arcs (' || char(27, 10, 200) || ')' WHERE name = 'arcs';"
expect safety-binary-schema 1 "^retrace: error: $ms/bad_schema.db: corrupt map: malformed database schema" -- \
  "$bin" inspect --map "$ms/bad_schema.db"
expect safety-binary-schema-printable 0 '^printable$' -- bash -c "out=\$('$bin' inspect --map '$ms/bad_schema.db' 2>&1)
  LC_ALL=C grep -q '[^[:print:]]' <<<\"\$out\" || echo printable"
