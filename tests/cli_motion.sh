#!/usr/bin/env bash
# cli_motion.sh: `crease motion` end to end: the clip list, clips written as
# .npz (read back through --input), a BVH converted, --json fields, and exit
# codes (0 ok, 1 bad input naming the file and line, 2 usage).
# Usage: cli_motion.sh PATH_TO_CREASE
source "$(dirname "$0")/lib_cli.sh" "$1"

# json_between FILE KEY LO HI: the number at KEY in FILE's last line is in (LO, HI)
json_between() {
  local v; v=$(tail -n 1 "$1" | grep -o "\"$2\":[-0-9.eE+]*" | head -n 1 | cut -d: -f2)
  [[ -n $v ]] && awk -v v="$v" -v lo="$3" -v hi="$4" 'BEGIN { exit !(v > lo && v < hi) }'
}

check "motion --help" bash -c "'$crease' motion --help | grep -q usage"
check "motion --list: 13 clips" bash -c "[[ \$('$crease' motion --list | wc -l) -eq 13 ]]"
check "motion --list --json" bash -c "'$crease' motion --list --json | grep -q '\"name\":\"raise_arms\"'"

# --- every clip, 40 frames, written and read back -----------------------------------------
for clip in walk run jump bend raise_arms squat twist dance stairs dodge reach lean stretch; do
  check "clip $clip" bash -c "'$crease' motion --clip $clip --frames 40 -o '$tmp/$clip.npz' --json \
    > '$tmp/$clip.json'"
  check "clip $clip back" bash -c "'$crease' motion --input '$tmp/$clip.npz' --json > '$tmp/$clip.in.json'"
  check "clip $clip 40 frames" grep -q '"frames":40,' "$tmp/$clip.in.json"
done
check "clip fields" json_has "$tmp/walk.json" command clip frames fps seconds output \
  max_angular_speed_rad_s max_angular_speed_joint
check "walk: 30 fps" grep -q '"fps":30,' "$tmp/walk.json"
check "walk: joints under 12 rad/s" json_between "$tmp/walk.json" max_angular_speed_rad_s 0.5 12
check "walk file: zip magic" bash -c "head -c 2 '$tmp/walk.npz' | grep -q PK"
check "clip --fps --speed" bash -c "'$crease' motion --clip run --frames 10 --fps 60 --speed 0.5 \
  -o '$tmp/slow.npz' --json | grep -q '\"fps\":60,'"

# --- a BVH (SMPL names, metres, facing -X), converted -------------------------------------
cat > "$tmp/turn.bvh" <<'EOF'
HIERARCHY
ROOT pelvis
{
  OFFSET 0 0 0
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT left_hip
  {
    OFFSET 0.09 -0.08 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT left_knee
    {
      OFFSET 0 -0.4 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT left_ankle
      {
        OFFSET 0 -0.42 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {
          OFFSET 0 -0.06 0.12
        }
      }
    }
  }
  JOINT right_hip
  {
    OFFSET -0.09 -0.08 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT right_knee
    {
      OFFSET 0 -0.4 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT right_ankle
      {
        OFFSET 0 -0.42 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        End Site
        {
          OFFSET 0 -0.06 0.12
        }
      }
    }
  }
  JOINT spine1
  {
    OFFSET 0 0.1 0
    CHANNELS 3 Zrotation Xrotation Yrotation
    JOINT spine2
    {
      OFFSET 0 0.13 0
      CHANNELS 3 Zrotation Xrotation Yrotation
      JOINT spine3
      {
        OFFSET 0 0.05 0
        CHANNELS 3 Zrotation Xrotation Yrotation
        JOINT neck
        {
          OFFSET 0 0.22 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT head
          {
            OFFSET 0 0.08 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {
              OFFSET 0 0.18 0
            }
          }
        }
        JOINT left_shoulder
        {
          OFFSET 0.18 0.16 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT left_elbow
          {
            OFFSET 0.27 0 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {
              OFFSET 0.25 0 0
            }
          }
        }
        JOINT right_shoulder
        {
          OFFSET -0.18 0.16 0
          CHANNELS 3 Zrotation Xrotation Yrotation
          JOINT right_elbow
          {
            OFFSET -0.27 0 0
            CHANNELS 3 Zrotation Xrotation Yrotation
            End Site
            {
              OFFSET -0.25 0 0
            }
          }
        }
      }
    }
  }
}
MOTION
Frames: 3
Frame Time: 0.04
EOF
# 51 values a frame: the root's 6 (facing -X, walking back 5 cm a frame), then 15 joints of 3
# (Z, X, Y) of which only the left knee's X moves: 20, 25, 30 degrees.
for f in 0 1 2; do
  printf '0 0.96 0.%d 0 0 -90 0 0 0 0 %d 0' $((f * 5)) $((20 + 5 * f))
  for k in $(seq 39); do printf ' 0'; done
  echo
done >> "$tmp/turn.bvh"
check "bvh convert" bash -c "'$crease' motion --input '$tmp/turn.bvh' -o '$tmp/turn.npz' --json > '$tmp/turn.json'"
check "bvh fields" json_has "$tmp/turn.json" command input frames fps output max_angular_speed_rad_s
check "bvh 25 fps" grep -q '"fps":25,' "$tmp/turn.json"
# the left knee goes 20 -> 25 -> 30 degrees: 5 degrees a frame at 25 fps is 2.18 rad/s
check "bvh knee speed" json_between "$tmp/turn.json" max_angular_speed_rad_s 2.1 2.3
check "bvh knee joint" grep -q '"max_angular_speed_joint":"left_knee"' "$tmp/turn.json"
check "bvh --fps" bash -c "'$crease' motion --input '$tmp/turn.bvh' --fps 50 --json > '$tmp/turn50.json'"
check "bvh 50 fps frames" grep -q '"frames":5,' "$tmp/turn50.json"
check "bvh source rate" grep -q '"source_fps":25,' "$tmp/turn50.json"
check "bvh frame range" bash -c "'$crease' motion --input '$tmp/turn.bvh' --start-frame 1 --end-frame 2 --json | grep -q '\"frames\":2,'"
expect_exit 1 "frames 0 to 2" motion --input "$tmp/turn.bvh" --start-frame 5
expect_exit 2 "read a file" motion --clip walk --scale 2 -o "$tmp/x.npz"
# simulate on a motion file: the mannequin posed by it, eased in from the rest pose
"$crease" garment --type tshirt --res 500 -o "$tmp/shirt.obj" >/dev/null 2>&1
check "simulate --motion" bash -c "'$crease' simulate --garment '$tmp/shirt.obj' --motion '$tmp/turn.bvh' \
  --ease-in 0.1 --frames 2 --quiet -o '$tmp/sim' --json | grep -q '\"frames\":2,'"
expect_exit 2 "--motion poses a body model" simulate --garment "$tmp/shirt.obj" \
  --motion "$tmp/turn.bvh" --object sphere --frames 2 -o "$tmp/sim"
check "bvh npz back" bash -c "'$crease' motion --input '$tmp/turn.npz' --json | grep -q '\"frames\":3,'"

# --- bad input and usage ------------------------------------------------------------------
head -n -1 "$tmp/turn.bvh" > "$tmp/short.bvh"
echo "0 0.96 0.1 0 0 -90" >> "$tmp/short.bvh"
expect_exit 1 "short.bvh:$(wc -l < "$tmp/short.bvh"): expected 51 channel values, got 6" \
  motion --input "$tmp/short.bvh" -o "$tmp/x.npz"
expect_exit 1 "nope.bvh" motion --input "$tmp/nope.bvh" -o "$tmp/x.npz"
printf 'PK\005\006not a zip' > "$tmp/bad.npz"
expect_exit 1 "bad.npz" motion --input "$tmp/bad.npz"
expect_exit 1 "walk.fbx" motion --input "$tmp/walk.fbx"
expect_exit 1 "written as .npz" motion --clip walk -o "$tmp/walk.bvh"
expect_exit 2 "unknown clip 'moonwalk'" motion --clip moonwalk -o "$tmp/x.npz"
expect_exit 2 "missing -o" motion --clip walk
expect_exit 2 "one of --clip" motion -o "$tmp/x.npz"
expect_exit 2 "--frames" motion --clip walk --frames 0 -o "$tmp/x.npz"
expect_exit 2 "--speed" motion --clip walk --speed 9 -o "$tmp/x.npz"
expect_exit 2 "shape a --clip" motion --input "$tmp/turn.bvh" --frames 3
expect_exit 2 "unknown option" motion --clip walk --bogus -o "$tmp/x.npz"
check "no partial file on failure" test ! -e "$tmp/x.npz"

echo "cli_motion: $passed passed, $failed failed"
[[ $failed -eq 0 ]]
