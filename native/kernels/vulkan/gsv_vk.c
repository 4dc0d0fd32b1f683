/*
 * gsv_vk.c -- a minimal Vulkan compute host for the remap kernels of native/kernels/ (the GLSL
 * 450 kernel and the HLSL one, both compiled to SPIR-V by glslang). A shared library, driven
 * through ctypes by tests/native_kernels.py (the conformance harness) and by the kernels'
 * benchmark; C99, links only libvulkan.
 *
 *   gsv_vk *gsv_vk_open(const uint32_t *spirv, size_t bytes, char *device, size_t device_len,
 *                       char *error, size_t error_len);
 *       instance, the first physical device (VK_ICD_FILENAMES picks the driver), a compute
 *       queue, the pipeline of the kernel (13 storage buffers at set 0, bindings 0..12).
 *   int gsv_vk_upload(gsv_vk *, unsigned binding, const void *data, size_t bytes);
 *       (re)fill a buffer; it grows when needed and is kept between dispatches.
 *   int gsv_vk_dispatch(gsv_vk *, uint32_t splats, uint32_t repeats, double *seconds);
 *       remap every splat `repeats` times (one submission, waited for); *seconds is the wall
 *       time of the submission and the wait. More than 65535 workgroups of 64 splats are
 *       dispatched as a 2D grid (binding 0, the kernel's params, must hold 5 uints).
 *   int gsv_vk_download(gsv_vk *, unsigned binding, void *data, size_t bytes);
 *   void gsv_vk_close(gsv_vk *);
 * The int functions return 0 on success, a VkResult or -1 otherwise. Memory is host visible
 * and coherent (lavapipe's is; a discrete GPU would want device-local buffers and staging
 * copies, which a benchmark of the kernel alone does not need).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <vulkan/vulkan.h>

#define GSV_VK_BINDINGS 13
#define GSV_VK_GROUP 64u          /* local_size_x / numthreads of the kernels */
#define GSV_VK_MAX_GROUPS 65535u  /* maxComputeWorkGroupCount[0] every device has */

typedef struct gsv_vk {
    VkInstance instance;
    VkPhysicalDevice physical;
    VkDevice device;
    VkQueue queue;
    uint32_t family;
    VkShaderModule module;
    VkDescriptorSetLayout set_layout;
    VkPipelineLayout pipeline_layout;
    VkPipeline pipeline;
    VkDescriptorPool pool;
    VkDescriptorSet set;
    VkCommandPool command_pool;
    VkFence fence;
    VkBuffer buffers[GSV_VK_BINDINGS];
    VkDeviceMemory memory[GSV_VK_BINDINGS];
    VkDeviceSize sizes[GSV_VK_BINDINGS];
    void *mapped[GSV_VK_BINDINGS];
} gsv_vk;

void gsv_vk_close(gsv_vk *vk);

static void gsv_vk__say(char *error, size_t len, const char *what, VkResult rc) {
    if (error && len) snprintf(error, len, "%s failed (VkResult %d)", what, (int)rc);
}

static int gsv_vk__memory_type(gsv_vk *vk, uint32_t bits, VkMemoryPropertyFlags want) {
    VkPhysicalDeviceMemoryProperties props;
    uint32_t i;
    vkGetPhysicalDeviceMemoryProperties(vk->physical, &props);
    for (i = 0; i < props.memoryTypeCount; ++i)
        if ((bits & (1u << i)) && (props.memoryTypes[i].propertyFlags & want) == want)
            return (int)i;
    return -1;
}

gsv_vk *gsv_vk_open(const uint32_t *spirv, size_t bytes, char *device_name, size_t device_len,
                    char *error, size_t error_len) {
    gsv_vk *vk = (gsv_vk *)calloc(1, sizeof(gsv_vk));
    VkResult rc;
    uint32_t count = 0, i;
    VkPhysicalDevice *devices;
    VkPhysicalDeviceProperties props;
    VkQueueFamilyProperties *families;
    float priority = 1.0f;
    VkDescriptorSetLayoutBinding bindings[GSV_VK_BINDINGS];
    VkApplicationInfo app = {VK_STRUCTURE_TYPE_APPLICATION_INFO};
    VkInstanceCreateInfo ici = {VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    VkDeviceQueueCreateInfo qci = {VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    VkDeviceCreateInfo dci = {VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    VkShaderModuleCreateInfo smci = {VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    VkDescriptorSetLayoutCreateInfo dslci = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
    VkPipelineLayoutCreateInfo plci = {VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
    VkComputePipelineCreateInfo cpci = {VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
    VkDescriptorPoolSize pool_size = {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, GSV_VK_BINDINGS};
    VkDescriptorPoolCreateInfo dpci = {VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO};
    VkDescriptorSetAllocateInfo dsai = {VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO};
    VkCommandPoolCreateInfo cpoolci = {VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    VkFenceCreateInfo fci = {VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    if (!vk) return NULL;

    app.pApplicationName = "gsverse-remap";
    app.apiVersion = VK_API_VERSION_1_0;
    ici.pApplicationInfo = &app;
    if ((rc = vkCreateInstance(&ici, NULL, &vk->instance)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateInstance", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    vkEnumeratePhysicalDevices(vk->instance, &count, NULL);
    if (count == 0) {
        if (error && error_len) snprintf(error, error_len, "no Vulkan device");
        gsv_vk_close(vk);
        return NULL;
    }
    devices = (VkPhysicalDevice *)calloc(count, sizeof(VkPhysicalDevice));
    vkEnumeratePhysicalDevices(vk->instance, &count, devices);
    vk->physical = devices[0];
    free(devices);
    vkGetPhysicalDeviceProperties(vk->physical, &props);
    if (device_name && device_len) snprintf(device_name, device_len, "%s", props.deviceName);

    vkGetPhysicalDeviceQueueFamilyProperties(vk->physical, &count, NULL);
    families = (VkQueueFamilyProperties *)calloc(count, sizeof(VkQueueFamilyProperties));
    vkGetPhysicalDeviceQueueFamilyProperties(vk->physical, &count, families);
    vk->family = count;
    for (i = 0; i < count; ++i)
        if (families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) { vk->family = i; break; }
    free(families);
    if (vk->family == count) {
        if (error && error_len) snprintf(error, error_len, "no compute queue");
        gsv_vk_close(vk);
        return NULL;
    }
    qci.queueFamilyIndex = vk->family;
    qci.queueCount = 1;
    qci.pQueuePriorities = &priority;
    dci.queueCreateInfoCount = 1;
    dci.pQueueCreateInfos = &qci;
    if ((rc = vkCreateDevice(vk->physical, &dci, NULL, &vk->device)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateDevice", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    vkGetDeviceQueue(vk->device, vk->family, 0, &vk->queue);

    smci.codeSize = bytes;
    smci.pCode = spirv;
    if ((rc = vkCreateShaderModule(vk->device, &smci, NULL, &vk->module)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateShaderModule", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    for (i = 0; i < GSV_VK_BINDINGS; ++i) {
        memset(&bindings[i], 0, sizeof(bindings[i]));
        bindings[i].binding = i;
        bindings[i].descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        bindings[i].descriptorCount = 1;
        bindings[i].stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
    }
    dslci.bindingCount = GSV_VK_BINDINGS;
    dslci.pBindings = bindings;
    if ((rc = vkCreateDescriptorSetLayout(vk->device, &dslci, NULL, &vk->set_layout))
        != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateDescriptorSetLayout", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    plci.setLayoutCount = 1;
    plci.pSetLayouts = &vk->set_layout;
    if ((rc = vkCreatePipelineLayout(vk->device, &plci, NULL, &vk->pipeline_layout))
        != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreatePipelineLayout", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    cpci.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cpci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cpci.stage.module = vk->module;
    cpci.stage.pName = "main";
    cpci.layout = vk->pipeline_layout;
    if ((rc = vkCreateComputePipelines(vk->device, VK_NULL_HANDLE, 1, &cpci, NULL,
                                       &vk->pipeline)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateComputePipelines", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    dpci.maxSets = 1;
    dpci.poolSizeCount = 1;
    dpci.pPoolSizes = &pool_size;
    if ((rc = vkCreateDescriptorPool(vk->device, &dpci, NULL, &vk->pool)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateDescriptorPool", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    dsai.descriptorPool = vk->pool;
    dsai.descriptorSetCount = 1;
    dsai.pSetLayouts = &vk->set_layout;
    if ((rc = vkAllocateDescriptorSets(vk->device, &dsai, &vk->set)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkAllocateDescriptorSets", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    cpoolci.queueFamilyIndex = vk->family;
    cpoolci.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    if ((rc = vkCreateCommandPool(vk->device, &cpoolci, NULL, &vk->command_pool)) != VK_SUCCESS
        || (rc = vkCreateFence(vk->device, &fci, NULL, &vk->fence)) != VK_SUCCESS) {
        gsv_vk__say(error, error_len, "vkCreateCommandPool/vkCreateFence", rc);
        gsv_vk_close(vk);
        return NULL;
    }
    return vk;
}

static void gsv_vk__free_buffer(gsv_vk *vk, unsigned b) {
    if (vk->mapped[b]) vkUnmapMemory(vk->device, vk->memory[b]);
    if (vk->buffers[b]) vkDestroyBuffer(vk->device, vk->buffers[b], NULL);
    if (vk->memory[b]) vkFreeMemory(vk->device, vk->memory[b], NULL);
    vk->mapped[b] = NULL;
    vk->buffers[b] = VK_NULL_HANDLE;
    vk->memory[b] = VK_NULL_HANDLE;
    vk->sizes[b] = 0;
}

/* A host-visible buffer of at least `bytes` at binding b, written into the descriptor set. */
static int gsv_vk__ensure(gsv_vk *vk, unsigned b, size_t bytes) {
    VkBufferCreateInfo bci = {VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    VkMemoryAllocateInfo mai = {VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    VkMemoryRequirements req;
    VkDescriptorBufferInfo info;
    VkWriteDescriptorSet write = {VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET};
    VkResult rc;
    int type;
    if (b >= GSV_VK_BINDINGS) return -1;
    if (bytes == 0) bytes = 16;          /* an empty array still needs a buffer */
    if (vk->buffers[b] && vk->sizes[b] >= bytes) return 0;
    gsv_vk__free_buffer(vk, b);
    bci.size = bytes;
    bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    if ((rc = vkCreateBuffer(vk->device, &bci, NULL, &vk->buffers[b])) != VK_SUCCESS)
        return (int)rc;
    vkGetBufferMemoryRequirements(vk->device, vk->buffers[b], &req);
    type = gsv_vk__memory_type(vk, req.memoryTypeBits, VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT
                               | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
    if (type < 0) return -1;
    mai.allocationSize = req.size;
    mai.memoryTypeIndex = (uint32_t)type;
    if ((rc = vkAllocateMemory(vk->device, &mai, NULL, &vk->memory[b])) != VK_SUCCESS)
        return (int)rc;
    if ((rc = vkBindBufferMemory(vk->device, vk->buffers[b], vk->memory[b], 0)) != VK_SUCCESS)
        return (int)rc;
    if ((rc = vkMapMemory(vk->device, vk->memory[b], 0, VK_WHOLE_SIZE, 0, &vk->mapped[b]))
        != VK_SUCCESS)
        return (int)rc;
    vk->sizes[b] = bytes;
    info.buffer = vk->buffers[b];
    info.offset = 0;
    info.range = VK_WHOLE_SIZE;
    write.dstSet = vk->set;
    write.dstBinding = b;
    write.descriptorCount = 1;
    write.descriptorType = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    write.pBufferInfo = &info;
    vkUpdateDescriptorSets(vk->device, 1, &write, 0, NULL);
    return 0;
}

int gsv_vk_upload(gsv_vk *vk, unsigned binding, const void *data, size_t bytes) {
    int rc = gsv_vk__ensure(vk, binding, bytes);
    if (rc == 0 && bytes) memcpy(vk->mapped[binding], data, bytes);
    return rc;
}

int gsv_vk_download(gsv_vk *vk, unsigned binding, void *data, size_t bytes) {
    if (binding >= GSV_VK_BINDINGS || !vk->mapped[binding] || vk->sizes[binding] < bytes)
        return -1;
    memcpy(data, vk->mapped[binding], bytes);
    return 0;
}

static double gsv_vk__now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int gsv_vk_dispatch(gsv_vk *vk, uint32_t splats, uint32_t repeats, double *seconds) {
    VkCommandBufferAllocateInfo cbai = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    VkCommandBufferBeginInfo begin = {VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    VkSubmitInfo submit = {VK_STRUCTURE_TYPE_SUBMIT_INFO};
    VkMemoryBarrier barrier = {VK_STRUCTURE_TYPE_MEMORY_BARRIER};
    VkCommandBuffer cb;
    VkResult rc;
    uint32_t r, groups = (splats + GSV_VK_GROUP - 1) / GSV_VK_GROUP, gx, gy;
    double t0;
    unsigned b;
    if (!vk->buffers[0] || vk->sizes[0] < 5 * sizeof(uint32_t)) return -1;
    for (b = 0; b < GSV_VK_BINDINGS; ++b)
        if ((rc = (VkResult)gsv_vk__ensure(vk, b, 16)) != VK_SUCCESS) return (int)rc;
    /* a 2D grid when one row of workgroups is not enough: splat x + y * 64 * gx */
    gx = groups < GSV_VK_MAX_GROUPS ? groups : GSV_VK_MAX_GROUPS;
    gy = gx ? (groups + gx - 1) / gx : 0;
    cbai.commandPool = vk->command_pool;
    cbai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    cbai.commandBufferCount = 1;
    if ((rc = vkAllocateCommandBuffers(vk->device, &cbai, &cb)) != VK_SUCCESS) return (int)rc;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    vkBeginCommandBuffer(cb, &begin);
    vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_COMPUTE, vk->pipeline);
    vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_COMPUTE, vk->pipeline_layout, 0, 1,
                            &vk->set, 0, NULL);
    barrier.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    barrier.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_SHADER_READ_BIT;
    for (r = 0; r < repeats; ++r) {
        if (gx) vkCmdDispatch(cb, gx, gy, 1);
        if (r + 1 < repeats)
            vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                                 VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 1, &barrier, 0, NULL,
                                 0, NULL);
    }
    barrier.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                         1, &barrier, 0, NULL, 0, NULL);
    vkEndCommandBuffer(cb);
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cb;
    vkResetFences(vk->device, 1, &vk->fence);
    t0 = gsv_vk__now();
    rc = vkQueueSubmit(vk->queue, 1, &submit, vk->fence);
    if (rc == VK_SUCCESS) rc = vkWaitForFences(vk->device, 1, &vk->fence, VK_TRUE, UINT64_MAX);
    if (seconds) *seconds = gsv_vk__now() - t0;
    vkFreeCommandBuffers(vk->device, vk->command_pool, 1, &cb);
    return (int)rc;
}

void gsv_vk_close(gsv_vk *vk) {
    unsigned b;
    if (!vk) return;
    if (vk->device) {
        vkDeviceWaitIdle(vk->device);
        for (b = 0; b < GSV_VK_BINDINGS; ++b) gsv_vk__free_buffer(vk, b);
        if (vk->fence) vkDestroyFence(vk->device, vk->fence, NULL);
        if (vk->command_pool) vkDestroyCommandPool(vk->device, vk->command_pool, NULL);
        if (vk->pool) vkDestroyDescriptorPool(vk->device, vk->pool, NULL);
        if (vk->pipeline) vkDestroyPipeline(vk->device, vk->pipeline, NULL);
        if (vk->pipeline_layout) vkDestroyPipelineLayout(vk->device, vk->pipeline_layout, NULL);
        if (vk->set_layout) vkDestroyDescriptorSetLayout(vk->device, vk->set_layout, NULL);
        if (vk->module) vkDestroyShaderModule(vk->device, vk->module, NULL);
        vkDestroyDevice(vk->device, NULL);
    }
    if (vk->instance) vkDestroyInstance(vk->instance, NULL);
    free(vk);
}
