local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.lua;" .. package.path
local image = require("vrshark.eclink_image")
image.proto()
