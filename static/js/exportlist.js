// The exports the exports panel offers: one entry per button, in order ({id, label, format, body, title}).
// WRITTEN FROM app/services/exports/formats.py
// (python -m app.services.exports.formats > static/js/exportlist.js);
// tests/services/exports/test_export_formats.py checks that the two agree. Do not edit the list here.

export const EXPORTS = /*EXPORTS*/[
 {
  "id": "soccernet-v3d",
  "label": "SoccerNet-v3D",
  "format": "soccernet-v3d",
  "body": {
   "images": true
  },
  "title": "Labels-v3D.json and Frames-v3.zip (the images) per game, and SNv3D.csv"
 },
 {
  "id": "soccernet-v3d-no-images",
  "label": "SoccerNet-v3D without images",
  "format": "soccernet-v3d",
  "body": {
   "images": false
  },
  "title": "Labels-v3D.json per game and SNv3D.csv, no images"
 },
 {
  "id": "issia-3d",
  "label": "ISSIA-3D",
  "format": "issia-3d",
  "body": {},
  "title": "per ISSIA sequence: ISSIA-3D.csv, split.json and the cameras"
 },
 {
  "id": "cameras",
  "label": "Cameras",
  "format": "cameras",
  "body": {},
  "title": "per image size: ground_truth.zip and predictions.zip as SoccerNet's calibration evaluator reads them"
 },
 {
  "id": "yolo",
  "label": "YOLO",
  "format": "yolo",
  "body": {},
  "title": "Ultralytics layout: images/, labels/, data.yaml (relocatable: no path key)"
 },
 {
  "id": "coco",
  "label": "COCO",
  "format": "coco",
  "body": {},
  "title": "per split: the images and instances.json"
 }
]/*END*/;
